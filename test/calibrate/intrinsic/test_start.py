"""The ranking of restarted fits (:func:`restart_order`): the same cost over the same observations,
ties within the noise decided by the extrapolation to the image corners."""

from dataclasses import replace

import numpy as np

from pascal_calib_ros.calibrate.intrinsic.options import CalibrationOptions
from pascal_calib_ros.calibrate.intrinsic.pipeline import Refined, first_refinement, prepare
from pascal_calib_ros.calibrate.intrinsic.start import corner_displacement, restart_order, view_costs
from pascal_calib_ros.calibrate.solver.refine import RefineResult
from pascal_calib_ros.geometry import ImageSize


def _moved(res: RefineResult, k1_step: float) -> RefineResult:
    """The fit with k1 (x[4]: fx, fy, cx, cy, k1, ...) moved by ``k1_step``, the rest kept."""
    assert res.x is not None
    x = res.x.copy()
    x[4] += k1_step
    D = res.D.copy()
    D[0] += k1_step
    return replace(res, x=x, D=D)


def test_restarts_are_ranked_by_the_cost_over_the_same_observations(ring_target, ring_session) -> None:
    _, _, dets = ring_session
    first = first_refinement(dets, ring_target, prepare(dets, ring_target, CalibrationOptions()))
    assert isinstance(first, Refined)
    res, idx = first.res, first.idx
    w, h = dets[0].width, dets[0].height
    costs = view_costs(res)
    # over all the observations it started with (its rejected ones too): at least its own cost
    assert len(costs) == len(idx) and float(np.sum(costs)) >= res.cost - 1e-12
    if sum(v.rejected_edges + v.rejected_corners for v in res.views) == 0:
        assert np.isclose(float(np.sum(costs)), res.cost, rtol=1e-9)
    # a fit off the minimum ranks after it, whatever RMS it reports (an RMS over fewer points is no score)
    off = replace(_moved(res, 2e-3), rms=0.5 * res.rms)
    assert restart_order([(off, idx), (res, idx)], ImageSize(w, h)) == [1, 0]
    # equal fits keep their order; within the noise, the fit that moves the corners least comes first
    assert restart_order([(res, idx), (res, idx)], ImageSize(w, h)) == [0, 1]
    # a fit of the same cost (its solution x kept) whose k3 bends the unobserved corners 0.8 px further
    near = replace(res, D=res.D - np.r_[0.0, 0.0, 0.0, 0.0, 0.03])
    assert corner_displacement(near, ImageSize(w, h)) > corner_displacement(res, ImageSize(w, h)) + 0.5
    assert restart_order([(near, idx), (res, idx)], ImageSize(w, h)) == [1, 0]
    assert restart_order([(near, idx), (off, idx)], ImageSize(w, h)) == [0, 1]  # but not against the data
