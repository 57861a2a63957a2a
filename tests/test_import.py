"""``import jaxtrack`` works without OpenCV or PyTorch importable."""

import subprocess
import sys
import textwrap


def test_import_without_cv2_or_torch():
    script = textwrap.dedent("""
        import sys

        class Block:
            def find_spec(self, name, path=None, target=None):
                if name.split(".")[0] in {"cv2", "torch", "kornia"}:
                    raise ImportError(f"blocked {name}")
                return None

        sys.meta_path.insert(0, Block())
        import jaxtrack
        import jaxtrack.smc, jaxtrack.body, jaxtrack.vision, jaxtrack.data, jaxtrack.cli
        jaxtrack.cli.build_parser()
        assert not any(m.split(".")[0] in {"cv2", "torch", "kornia"} for m in sys.modules)
        try:
            import cv2  # noqa: F401
        except ImportError:
            print("blocked-ok")
    """)
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 0, result.stderr[-3000:]
    assert "blocked-ok" in result.stdout
