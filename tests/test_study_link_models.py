"""Imperfection studies against closed forms: the two link models' exact maximum loads and Koiter's laws."""

import numpy as np
import pytest

from shellform.scene import parse_scene
from shellform.studies.link_models import critical_load, exact_knockdown, link_scene, path_load
from shellform.studies.sample import run_sample
from shellform.studies.statistics import knockdown_exponent

if __import__("sys").version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib


def knockdown(kind: str, a: float) -> float:
    """The computed knock-down of the link model with its foot moved by ``a`` (its critical mode)."""
    scene = parse_scene(tomllib.loads(link_scene(kind)))
    delta = np.zeros((3, 3))
    delta[1, 0] = a
    record = run_sample(scene, delta, 1.0)
    assert record["status"] == "finished" and record["event"] == "limit", record
    return record["lam_cr"] / critical_load(kind)


def test_the_closed_forms_agree_with_their_own_path():
    # the symmetric closed form is the largest load of the explicit path, found by brute force
    for a in (1e-4, 1e-2):
        x = np.linspace(a * 1.0001, 0.6, 400_001)
        assert np.nanmax(path_load("symmetric", x, a)) / critical_load("symmetric") == pytest.approx(
            exact_knockdown("symmetric", a), abs=1e-9)
    # the asymmetric maximum found to round-off is the brute-force one too
    x = np.linspace(-0.4, -1e-3 * 1.0001, 400_001)
    assert np.nanmax(path_load("asymmetric", x, -1e-3)) / critical_load("asymmetric") == pytest.approx(
        exact_knockdown("asymmetric", -1e-3), abs=1e-9)


@pytest.mark.parametrize("kind, sign", [("symmetric", 1.0), ("asymmetric", -1.0)])
def test_knockdown_matches_the_exact_curve_over_three_decades(kind, sign):
    amplitudes = [1e-6, 1e-5, 1e-4, 1e-3]
    computed = [knockdown(kind, sign * a) for a in amplitudes]
    exact = [exact_knockdown(kind, sign * a) for a in amplitudes]
    np.testing.assert_allclose(computed, exact, rtol=0, atol=1e-6)
    fit = knockdown_exponent(amplitudes, computed)
    expected = 2.0 / 3.0 if kind == "symmetric" else 0.5
    assert fit["exponent"] == pytest.approx(expected, rel=0.02)


def test_the_perfect_models_bifurcate_at_the_exact_load():
    for kind in ("symmetric", "asymmetric"):
        record = run_sample(parse_scene(tomllib.loads(link_scene(kind))), np.zeros((3, 3)), 1.0)
        assert record["event"] == "bifurcation"
        # a bifurcation is located by bisection on the count of negative eigenvalues: to about 1e-6
        assert record["lam_cr"] == pytest.approx(critical_load(kind), rel=2e-6)


def test_koiter_classes_of_the_link_models_from_their_secondary_paths():
    from shellform.studies.post_buckling import post_buckling

    symmetric = post_buckling(parse_scene(tomllib.loads(link_scene("symmetric"))), 45.0)
    asymmetric = post_buckling(parse_scene(tomllib.loads(link_scene("asymmetric"))), 45.0)
    assert symmetric == {"+": "falls", "-": "falls", "class": "unstable-symmetric"}
    assert asymmetric["class"] == "asymmetric" and {asymmetric["+"], asymmetric["-"]} == {"rises", "falls"}
