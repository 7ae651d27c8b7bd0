import numpy as np
import pytest

from pascal_calib_ros.geometry.conic import (
    ConicFitError,
    Ellipse,
    conic_curvature,
    ellipses_from_conics,
    fit_conic,
    fit_conic_algebraic,
    fit_conics_algebraic,
    group_medians,
    line_conic_intersection,
    normalize_conic,
    sampson_distance,
    sampson_distances,
)


def test_fit_recovers_exact_ellipse() -> None:
    e = Ellipse(310.0, 240.0, 120.0, 70.0, 0.4)
    pts = e.sample(40)
    C = fit_conic(pts)
    assert np.allclose(C, e.to_conic(), atol=1e-10)
    back = Ellipse.from_conic(C)
    assert np.allclose([back.cx, back.cy, back.a, back.b], [310, 240, 120, 70], atol=1e-7)


def test_geometric_refinement_beats_algebraic_on_noisy_partial_arc() -> None:
    e = Ellipse(300.0, 200.0, 150.0, 60.0, 0.3)
    rng = np.random.default_rng(3)
    errs_alg, errs_geo = [], []
    for _ in range(20):
        t = rng.uniform(0, 2.5, 60)
        pts = np.stack([e.cx + e.a * np.cos(t) * np.cos(e.angle) - e.b * np.sin(t) * np.sin(e.angle),
                        e.cy + e.a * np.cos(t) * np.sin(e.angle) + e.b * np.sin(t) * np.cos(e.angle)], 1)
        pts += rng.normal(0, 0.5, pts.shape)
        truth = e.sample(200)
        errs_alg.append(np.sqrt(np.mean(sampson_distance(fit_conic_algebraic(pts), truth) ** 2)))
        errs_geo.append(np.sqrt(np.mean(sampson_distance(fit_conic(pts), truth) ** 2)))
    assert np.median(errs_geo) < np.median(errs_alg)


def test_degenerate_points_raise() -> None:
    with pytest.raises(ConicFitError):
        fit_conic(np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0], [3.0, 3.0], [4.0, 4.0], [5.0, 5.0]]))
    with pytest.raises(ConicFitError):
        fit_conic(np.zeros((3, 2)))


def test_normalisation_fixes_scale_and_sign() -> None:
    C = Ellipse(1, 2, 3, 2, 0.1).to_conic()
    assert np.allclose(normalize_conic(-5 * C), C)
    assert np.isclose(np.linalg.norm(C), 1) and C[0, 0] + C[1, 1] > 0


def test_curvature_of_a_circle() -> None:
    C = Ellipse(0, 0, 50.0, 50.0, 0).to_conic()
    pts = Ellipse(0, 0, 50.0, 50.0, 0).sample(10)
    assert np.allclose(conic_curvature(C, pts), 1 / 50.0)


def test_line_misses_circle_in_complex_points() -> None:
    C = Ellipse(0, 0, 1.0, 1.0, 0).to_conic()
    p, q = line_conic_intersection(np.array([0.0, 1.0, -2.0]), C)  # y = 2
    for r in (p, q):
        r = r / r[2]
        assert abs(r[1] - 2) < 1e-12 and abs(r[0] ** 2 + r[1] ** 2 - 1) < 1e-12 and abs(r[0].imag) > 1


def test_batched_fits_match_one_at_a_time() -> None:
    """fit_conics_algebraic, ellipses_from_conics, sampson_distances and group_medians (used by
    the grid detector) agree with their one-curve counterparts; degenerate groups are flagged."""
    rng = np.random.default_rng(3)
    sets = []
    for _ in range(30):
        e = Ellipse(rng.uniform(0, 1000), rng.uniform(0, 700), rng.uniform(5, 30), rng.uniform(4, 25),
                    rng.uniform(0, 3))
        n = int(rng.integers(12, 80))
        sets.append(e.sample(n) + rng.normal(0, 0.1, (n, 2)))
    sets.append(np.array([[0.0, 0.0], [1, 1], [2, 2], [3, 3], [4, 4]]))  # collinear
    sets.append(np.array([[0.0, 0.0], [1, 2]]))  # too few points
    pts = np.concatenate(sets)
    owner = np.repeat(np.arange(len(sets)), [len(s) for s in sets])
    C, ok = fit_conics_algebraic(pts, owner, len(sets) + 1)  # one empty group at the end
    assert ok[:30].all() and not ok[30:].any()
    par, real = ellipses_from_conics(C[:30])
    assert real.all()
    d = sampson_distances(C, pts, owner)
    med = group_medians(np.abs(d), owner, len(sets) + 1)
    for k in range(30):
        ref = fit_conic_algebraic(sets[k])
        assert np.allclose(C[k], ref, atol=1e-12)
        e = Ellipse.from_conic(ref)
        assert np.allclose(par[k, :4], [e.cx, e.cy, e.a, e.b], atol=1e-8)
        assert np.isclose(med[k], np.median(np.abs(sampson_distance(ref, sets[k]))))
    assert np.isnan(med[-1])


def test_line_conic_intersection_has_no_cancellation() -> None:
    """Roots of very different size (a line nearly through the conic's far side): the small root
    keeps its relative accuracy (the textbook formula loses it to cancellation)."""
    C = Ellipse(0.0, 0.0, 1.0, 1.0, 0.0).to_conic()
    for y in (0.999999, 1 - 1e-9):
        line = np.array([0.0, 1.0, -y])
        for r in line_conic_intersection(line, C):
            r = r / r[2]
            assert abs(r[0] ** 2 + r[1] ** 2 - 1) < 1e-13
