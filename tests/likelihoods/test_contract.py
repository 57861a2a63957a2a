"""The part contract (``jaxtrack.likelihoods._base``): what every appearance likelihood declares,
the one marker-shape check, and the package's import hygiene."""

import ast
import inspect
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxtrack.likelihoods as likelihoods
from jaxtrack.body import SPM_MARKERS
from jaxtrack.likelihoods import (
    EdgeLimbTemplates,
    LimbTemplates,
    NCCTemplates,
    PartTemplates,
    make_appearance_templates,
)
from jaxtrack.likelihoods._base import NUM_MARKERS, SPINE_MARKERS, check_markers

PACKAGE = Path(likelihoods.__file__).parent
CONTRACT_METHODS = ("log_likelihood", "residuals", "part_log_likelihoods", "part_residuals")


def tiny_pose():
    """A 64 × 48 frame with some texture and a pose whose strips and patches fit inside it."""
    y, x = np.mgrid[0:48, 0:64].astype(np.float32)
    image = (0.5 + 0.25 * np.sin(x / 3.0) * np.cos(y / 4.0) + 0.002 * x * y / 48).astype(
        np.float32)
    markers = np.array([[32, 6], [32, 12], [32, 20], [32, 30],  # head, neck, thorax, pelvis
                        [24, 13], [18, 20], [14, 28], [27, 31],  # right arm and hip
                        [40, 13], [46, 20], [50, 28], [37, 31]], np.float32)
    return image, markers


class _Methods(PartTemplates):
    """The contract's four methods for a toy likelihood, one part per marker; the attributes
    are left to subclasses."""

    weight: jax.Array

    def log_likelihood(self, markers_2d, observation, sharpness, nearest=True):
        return jnp.sum(self.part_log_likelihoods(markers_2d, observation, sharpness, nearest))

    def residuals(self, markers_2d, observation, sharpness, spine=None):
        return jnp.sqrt(2 * sharpness * self.weight) * jnp.asarray(markers_2d).reshape(-1)

    def part_log_likelihoods(self, markers_2d, observation, sharpness, nearest=True,
                             parts=None):
        return -sharpness * self.weight * jnp.sum(jnp.asarray(markers_2d) ** 2, axis=-1)

    def part_residuals(self, markers_2d, observation, sharpness, spine=None):
        return self.residuals(markers_2d, observation, sharpness).reshape(NUM_MARKERS, 2)


class _Parts(_Methods):
    """The toy likelihood with its attributes: it keeps the contract."""

    part_markers = tuple((marker,) for marker in range(NUM_MARKERS))
    direct_part_markers = part_markers
    spine_markers = None


def test_every_appearance_likelihood_keeps_the_contract():
    image, markers = tiny_pose()
    for kind in ("markers", "limbs", "limbs+edges"):
        templates = make_appearance_templates(kind, image, markers)
        assert isinstance(templates, PartTemplates), kind
        assert len(templates.part_markers) == len(templates.direct_part_markers), kind
        assert templates.num_parts == len(templates.part_markers), kind
        assert all(0 <= m < NUM_MARKERS for part in templates.part_markers for m in part), kind
    for cls in (NCCTemplates, LimbTemplates, EdgeLimbTemplates):
        assert issubclass(cls, PartTemplates)
        for name in CONTRACT_METHODS:  # the signatures the trackers call, positionally
            base, own = (list(inspect.signature(getattr(owner, name)).parameters.values())
                         for owner in (PartTemplates, cls))
            assert [(p.kind, p.default) for p in own] == [(p.kind, p.default) for p in base], (
                cls, name)


def test_a_likelihood_missing_the_contract_cannot_be_made():
    assert float(_Parts(jnp.float32(1.0)).log_likelihood(jnp.ones((12, 2)), None, 1.0)) == -24.0

    class NoPartMarkers(_Methods):
        direct_part_markers = ((0,),)
        spine_markers = None

    with pytest.raises(TypeError, match="part_markers"):
        NoPartMarkers(jnp.float32(1.0))

    class NoResiduals(PartTemplates):
        part_markers = ((0,),)
        direct_part_markers = ((0,),)
        spine_markers = None

        def log_likelihood(self, markers_2d, observation, sharpness, nearest=True):
            return jnp.zeros(())

        def part_log_likelihoods(self, markers_2d, observation, sharpness, nearest=True,
                                 parts=None):
            return jnp.zeros(1)

        def part_residuals(self, markers_2d, observation, sharpness, spine=None):
            return jnp.zeros((1, 1))

    with pytest.raises(TypeError, match="residuals"):
        NoResiduals()
    with pytest.raises(TypeError, match="abstract"):
        PartTemplates()


def test_the_contract_checks_how_parts_read_the_spine():
    class ReadsTooMuch(_Parts):
        # part 0 says it depends on marker 0 only but reads marker 1 directly
        direct_part_markers = ((0, 1),) + tuple((m,) for m in range(1, NUM_MARKERS))

    with pytest.raises(ValueError, match="part 0 depends on markers"):
        ReadsTooMuch(jnp.float32(1.0))

    class Mismatched(_Parts):
        direct_part_markers = ((0,),)

    with pytest.raises(ValueError, match="names 1 parts but part_markers 12"):
        Mismatched(jnp.float32(1.0))

    class ThroughSpine(_Parts):  # each part also reads the spine length: a valid declaration
        part_markers = tuple((m, *SPINE_MARKERS) for m in range(NUM_MARKERS))
        spine_markers = SPINE_MARKERS

    assert ThroughSpine(jnp.float32(1.0)).num_parts == NUM_MARKERS


def test_marker_set_comes_from_the_body():
    assert NUM_MARKERS == len(SPM_MARKERS) == 12
    assert SPINE_MARKERS == (SPM_MARKERS.index("neck"), SPM_MARKERS.index("pelvis"))
    for name, start, end, _, _ in likelihoods.LIMB_SEGMENTS:
        assert start < NUM_MARKERS and end < NUM_MARKERS, name


def test_the_marker_check_names_the_expected_count():
    check_markers(np.zeros((12, 2)))
    check_markers(np.zeros((3, 5, 12, 2)), batched=True)
    with pytest.raises(ValueError, match=r"must be 12 \(x, y\).*\(12, 2\).*got shape \(11, 2\)"):
        check_markers(np.zeros((11, 2)))
    with pytest.raises(ValueError, match=r"\(\.\.\., 12, 2\).*got shape \(4, 12, 3\)"):
        check_markers(np.zeros((4, 12, 3)), batched=True)
    with pytest.raises(ValueError, match=r"pose must be 12 finite .*non-finite"):
        check_markers(np.full((12, 2), np.nan), name="pose", finite=True)
    # shapes are checked under jit too (the strips' points), finiteness needs concrete values
    jax.jit(lambda m: check_markers(m) or m)(jnp.zeros((12, 2)))
    with pytest.raises(ValueError, match="got shape"):
        jax.jit(lambda m: check_markers(m) or m)(jnp.zeros((13, 2)))
    with pytest.raises(ValueError, match="concrete"):
        jax.jit(lambda m: check_markers(m, finite=True) or m)(jnp.zeros((12, 2)))


@pytest.mark.parametrize("call", ["patch_half_size", "limb_points", "make_limb_templates",
                                  "fit_border_widths"])
def test_every_likelihood_uses_the_one_marker_check(call):
    image, markers = tiny_pose()
    wrong = markers[:11]
    with pytest.raises(ValueError, match=r"12 .*\(x, y\) pixel markers"):
        if call == "patch_half_size":
            likelihoods.patch_half_size(wrong)
        elif call == "limb_points":
            likelihoods.limb_points(wrong)
        elif call == "make_limb_templates":
            likelihoods.make_limb_templates(image, wrong)
        else:
            observation = np.stack([image, np.ones_like(image), np.zeros_like(image)])
            templates = likelihoods.make_edge_limb_templates(observation, markers,
                                                             border_scales=None)
            likelihoods.fit_border_widths(templates, observation, wrong)


def test_patches_take_no_spine_length():
    image, markers = tiny_pose()
    templates = make_appearance_templates("markers", image, markers)
    assert templates.spine_markers is None
    assert templates.part_residuals(markers, image, 1.0).shape[0] == NUM_MARKERS
    with pytest.raises(ValueError, match="spine"):
        templates.part_residuals(markers, image, 1.0, spine=jnp.float32(20.0))


def _private_imports(path: Path) -> list[str]:
    """``module.name`` for every underscore name imported from another jaxtrack module, and
    every ``module._name`` attribute read off an imported jaxtrack module."""
    tree = ast.parse(path.read_text())
    found = []
    modules = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("jaxtrack"):
            found += [f"{node.module}.{alias.name}" for alias in node.names
                      if alias.name.startswith("_") and not alias.name.startswith("__")]
        elif isinstance(node, ast.Import):
            modules.update({alias.asname or alias.name: alias.name for alias in node.names
                            if alias.name.startswith("jaxtrack")})
    for node in ast.walk(tree):
        if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                and node.value.id in modules and node.attr.startswith("_")
                and not node.attr.startswith("__")):
            found.append(f"{modules[node.value.id]}.{node.attr}")
    return found


def test_no_module_imports_another_modules_private_names():
    files = sorted(PACKAGE.glob("*.py"))
    assert {"_base.py", "_sampling.py", "_correlation.py", "_strips.py", "ncc.py", "limbs.py",
            "edges.py"} <= {path.name for path in files}
    offending = {path.name: _private_imports(path) for path in files}
    assert not any(offending.values()), offending


def test_the_private_import_check_can_fail(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text("from jaxtrack.likelihoods.ncc import _no_spine, ncc_scores\n"
                   "import jaxtrack.likelihoods.limbs as limbs\n"
                   "x = limbs._strips\n")
    assert _private_imports(bad) == ["jaxtrack.likelihoods.ncc._no_spine",
                                     "jaxtrack.likelihoods.limbs._strips"]
