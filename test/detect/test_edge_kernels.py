"""The compiled edge-fit kernels (detect/edge_kernels.py, geometry/conic_kernels.py) against the
numpy implementations they replace (test/edge_fits_numpy.py) and against scipy's functions."""

import numpy as np
import pytest
from edge_fits_numpy import fit_band_profiles as band_numpy
from edge_fits_numpy import fit_step_profiles as step_numpy
from edge_fits_numpy import refine_ellipse_numpy
from scipy.special import ndtr

from pascal_calib_ros.detect.edges import fit_band_profiles, fit_step_profiles
from pascal_calib_ros.geometry.conic import Ellipse


def test_normal_cdf_and_density_to_float32_precision() -> None:
    from numba import njit

    from pascal_calib_ros.detect import edge_kernels as K

    @njit
    def both(z: np.ndarray) -> np.ndarray:
        out = np.empty((2, z.size))
        for i in range(z.size):
            out[0, i], out[1, i] = K._phi_and_cdf(z[i])
        return out

    z = np.concatenate([np.linspace(-40, 40, 200001), [0.0, -0.0, 1e-300, -1e-300]])
    phi, cdf = both(z)
    assert np.abs(cdf - ndtr(z)).max() < 8e-8  # Abramowitz & Stegun 7.1.26: |erf error| <= 1.5e-7
    exact_phi = np.exp(-0.5 * z * z) / np.sqrt(2 * np.pi)
    # relative error of e^v below 1e-15 (1 + |v|): the rounding of v = -z²/2 itself
    assert np.all(np.abs(phi - exact_phi) <= 1e-15 * (1 + z * z) * exact_phi + 1e-300)
    assert np.all(np.diff(cdf[:200001]) >= 0)  # monotone: the fit's model cannot fold


def _step_profiles(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    s = np.arange(-6, 6.01, 0.5)
    s0, w, c = rng.uniform(-2, 2, n), rng.uniform(0.5, 2.5, n), rng.uniform(-150, 150, n)
    prof = 60 + 0.5 * s + c[:, None] * ndtr((s - s0[:, None]) / w[:, None]) + rng.normal(0, 2, (n, len(s)))
    return prof.astype(np.float32), s


@pytest.mark.parametrize("iterations", [3, 5, 8])
def test_step_fit_matches_numpy(iterations: int) -> None:
    """Same start, damping and acceptance as the numpy fit: the same edges, 99 % of them to
    1e-5 px, all to 1e-3 px (the normal CDF differs by < 8e-8, which can turn one accepted step
    of an unconverged fit into a refused one; grey-level noise moves an edge by ~0.05 px)."""
    prof, s = _step_profiles(400, iterations)
    got = np.stack(fit_step_profiles(prof, s, 1.0, iterations), 1)
    ref = np.stack(step_numpy(prof, s, 1.0, iterations), 1)
    d = np.abs(got[:, 0] - ref[:, 0])
    assert np.quantile(d, 0.99) < 1e-5 and d.max() < 1e-3  # s0, px
    assert np.abs(got[:, 1] - ref[:, 1]).max() < 1e-3  # blur, px
    assert np.abs(got[:, 2] - ref[:, 2]).max() < 1e-2  # contrast, grey levels
    assert np.abs(got[:, 3] - ref[:, 3]).max() < 1e-5  # RMS residual
    # per-profile offsets (n, m) as the grid batch passes them
    S = s[None, :] + np.linspace(-0.3, 0.3, len(prof))[:, None]
    got2 = np.stack(fit_step_profiles(prof, S, 1.0, iterations), 1)
    assert np.abs(got2[:, 0] - np.stack(step_numpy(prof, S, 1.0, iterations), 1)[:, 0]).max() < 1e-3


def test_band_fit_matches_numpy() -> None:
    """The band fit (numpy ran it in float32) gives the same two edges to 1e-3 px."""
    rng = np.random.default_rng(5)
    n, m = 300, 49
    lo, hi, w = rng.uniform(-3, -1, n), rng.uniform(1, 3, n), rng.uniform(0.6, 1.5, n)
    S = (lo - 4)[:, None] + np.linspace(0, 1, m)[None] * (hi - lo + 8)[:, None]
    band = ndtr((S - lo[:, None]) / w[:, None]) - ndtr((S - hi[:, None]) / w[:, None])
    prof = (200 + 0.3 * S - 150 * band + rng.normal(0, 2, (n, m))).astype(np.float32)
    lo0, hi0 = lo + rng.normal(0, 0.2, n), hi + rng.normal(0, 0.2, n)
    p, r = fit_band_profiles(prof, S, lo0, hi0, np.full(n, 1.0), 4)
    p_ref, r_ref = band_numpy(prof, S, lo0, hi0, 1.0, 4)
    assert np.abs(p[:, [3, 5]] - p_ref[:, [3, 5]]).max() < 1e-3
    assert np.abs(p[:, [4, 6]] - p_ref[:, [4, 6]]).max() < 1e-3
    assert np.abs(r - r_ref).max() < 1e-3
    assert np.abs(p[:, 3] - lo).mean() < 0.1 and np.abs(p[:, 5] - hi).mean() < 0.1  # and it fits


def test_bad_profiles_give_nan_or_a_refused_step_not_a_crash() -> None:
    prof, s = _step_profiles(6, 1)
    prof[0] = np.nan
    prof[1] = 7.0  # flat: no edge
    s0, _w, c, rms = fit_step_profiles(prof, s, 1.0, 5)
    assert np.isnan(rms[0]) and np.isfinite(s0[1:]).all() and abs(c[1]) < 1e-6


@pytest.mark.parametrize("seed", range(4))
def test_ellipse_refinement_matches_numpy(seed: int) -> None:
    rng = np.random.default_rng(seed)
    e = Ellipse(rng.uniform(100, 500), rng.uniform(100, 400), rng.uniform(20, 200), rng.uniform(10, 20),
                rng.uniform(-3, 3))
    pts = e.sample(300) + rng.normal(0, 0.3, (300, 2))
    start = np.array([e.cx + 1.0, e.cy - 0.5, e.a * 1.02, e.b * 0.97, e.angle + 0.02])
    from pascal_calib_ros.geometry import conic_kernels

    got = conic_kernels.refine_ellipse(start, pts, 10)
    ref = refine_ellipse_numpy(start, pts, 10)
    assert np.abs(got - ref).max() < 1e-6  # px and rad; the stopping test ends both within this


def test_group_moments_match_numpy() -> None:
    """The per-group scatter matrices of the batched algebraic conic fit, against numpy."""
    from pascal_calib_ros.geometry import conic_kernels

    rng = np.random.default_rng(2)
    owner = np.sort(rng.integers(0, 7, 400))
    owner[owner == 3] = 4  # an empty group
    pts = rng.normal(0, 30, (400, 2)) + owner[:, None] * 100.0
    counts, mean, scale, S = conic_kernels.group_conic_moments(pts, owner, 7)
    for g in range(7):
        p = pts[owner == g]
        assert counts[g] == len(p)
        if not len(p):
            assert np.all(S[g] == 0)
            continue
        m = p.mean(0)
        sc = np.sqrt(2) / np.linalg.norm(p - m, axis=1).mean()
        q = (p - m) * sc
        D = np.stack([q[:, 0] ** 2, q[:, 0] * q[:, 1], q[:, 1] ** 2, q[:, 0], q[:, 1], np.ones(len(q))], 1)
        assert np.allclose(mean[g], m, rtol=1e-13) and np.isclose(scale[g], sc, rtol=1e-13)
        assert np.allclose(S[g], D.T @ D, rtol=1e-12, atol=1e-12)


def test_detection_uses_one_compiled_version_of_each_kernel() -> None:
    """numba compiles a kernel once per argument type (seconds each on a cold cache): whatever
    the detection passes (float32 or float64 profiles, read-only views), each kernel runs one
    version, the one ``compile_all`` (make venv) builds. In a fresh process: other tests may
    call the kernels with other types."""
    import subprocess
    import sys

    code = """
import numpy as np
from pascal_calib_ros.detect import edge_kernels as K
from pascal_calib_ros.detect.target_detector import detect_target
from pascal_calib_ros.geometry import conic_kernels as CK
from pascal_calib_ros.sim.session import SessionSpec, render_session_views
from pascal_calib_ros.targets import resolve_target
K.compile_all()
for name in ("ring_a4", "ring_grid_a4", "pascal_board_a3"):
    _, views = render_session_views(resolve_target(name), SessionSpec(width=640, height=480, views=1, seed=4))
    img = views[0].image
    for im in (img, img.astype(np.float32), img.astype(np.uint16) * 257):
        assert detect_target(im, resolve_target(name)).ok
print([len(f.signatures) for f in (K.fit_step_rows, K.fit_band_rows, CK.refine_ellipse, CK.group_conic_moments)])
"""
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip().splitlines()[-1] == "[1, 1, 1, 1]", r.stdout
