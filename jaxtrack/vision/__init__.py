"""Image preprocessing with OpenCV, at the edge: frames in, NumPy arrays out.

OpenCV (and the optional kornia/torch) is imported lazily inside functions, so importing this
package does not need them.
"""

from jaxtrack.vision.contours import resample_closed_curve, signed_area, silhouette_contour

__all__ = ["resample_closed_curve", "signed_area", "silhouette_contour"]
