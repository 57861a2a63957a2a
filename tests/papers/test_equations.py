"""Every equation of Tian, Li & Sclaroff (2005), eq. 1–7, is cited by number in the code that
implements it: the module names the paper, and the implementing function or class (its
docstring or the comments in its body) names the equation."""

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

# eq. → (file, implementing object, what the equation is)
TIAN_EQUATIONS = {
    1: ("jaxtrack/priors/gplvm/_kernel.py", "active_objective",
        "GPLVM objective L = D/2 ln|K| + ½ Σ_m Y_mᵀK⁻¹Y_m + ½ Σ_i |x_i|²"),
    2: ("jaxtrack/priors/gplvm/_model.py", "GPLVM.point_objective",
        "L′(x_j, y_j) of a non-active point"),
    3: ("jaxtrack/priors/gplvm/_model.py", "GPLVM.mean", "μ(x) = Yᵀ K_II⁻¹ k_I(x)"),
    4: ("jaxtrack/priors/gplvm/_model.py", "GPLVM.variance",
        "σ²(x) = k(x, x) − k_Iᵀ K_II⁻¹ k_I"),
    5: ("jaxtrack/priors/gplvm/_model.py", "GPLVM.inverse", "μ⁻¹(y) = argmin_x L′(x, y)"),
    6: ("jaxtrack/priors/dynamics.py", "LatentWalk.sample",
        "latent random walk x_{t+1} = x_t + ω, ω ~ N(0, diag ν²) (Algorithm 2)"),
    7: ("jaxtrack/likelihoods/ncc.py", "ncc_log_likelihood",
        "p(z | y) ∝ exp(−Σ_m (1 − NCC_m))"),
}


def cites(text: str, number: int) -> bool:
    """Whether ``text`` cites ``eq. N`` (or ``Eq. (N)``); ``eq. 16`` and ``eq. 6.20`` do not
    cite 1 or 6, and a range ``eqs. 1–4`` cites no single equation."""
    return re.search(rf"\beq\.\s*\(?{number}(?!\d|\.\d)", text, re.IGNORECASE) is not None


def find_object(tree: ast.Module, dotted: str) -> ast.AST:
    node: ast.AST = tree
    for name in dotted.split("."):
        matches = [child for child in ast.iter_child_nodes(node)
                   if isinstance(child, (ast.FunctionDef, ast.ClassDef)) and child.name == name]
        assert matches, f"{dotted}: no {name!r}"
        node = matches[0]
    return node


def test_every_equation_has_a_home():
    assert sorted(TIAN_EQUATIONS) == list(range(1, 8))


@pytest.mark.parametrize("number", sorted(TIAN_EQUATIONS))
def test_equation_cited_where_implemented(number):
    path, dotted, what = TIAN_EQUATIONS[number]
    source = (ROOT / path).read_text(encoding="utf-8")
    assert "Tian" in source, f"{path} does not name Tian et al."
    node = find_object(ast.parse(source), dotted)
    segment = ast.get_source_segment(source, node)
    assert cites(segment, number), (
        f"Tian et al. eq. {number} ({what}) is not cited in {path}:{dotted}")


def test_citation_pattern():
    assert cites("Tian et al. eq. 6: random walk", 6)
    assert cites("(Tian et al. 2005, eq. 7)", 7)
    assert cites("Eq. (3)", 3)
    assert not cites("eq. 16", 1)
    assert not cites("Nocedal & Wright eq. 6.20", 6)
    assert not cites("eq. 2", 1)
