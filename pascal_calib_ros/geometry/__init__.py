"""Geometry without images or ROS: conics and the circular points of a ring (Pascal's theorem), the
image of the absolute conic and K, the lens models behind one interface, the camera, the one pose
type (:class:`Transform`), homographies, regions of an image and where a model holds."""

from .camera import Camera, rectified_projection
from .circular import (
    CircularPointError,
    circular_point_pt2,
    circular_points_from_ring,
    circular_points_huang,
    circular_points_pt1,
)
from .conic import ConicFitError, fit_conic
from .homography import fit_homography
from .iac import DegenerateViewsError, IacSolution, iac_from_circular_points
from .image_field import grid_pixels, hulls_mask, observed_field_mask, view_hulls
from .lens import DISTORTION_CHOICES, LensModel, lens_model
from .model_field import consistent_rays, distortion_field, model_valid
from .transform import Transform, TransformError

__all__ = ["DISTORTION_CHOICES", "Camera", "CircularPointError", "ConicFitError", "DegenerateViewsError", "IacSolution",
           "LensModel", "Transform", "TransformError", "circular_point_pt2", "circular_points_from_ring",
           "circular_points_huang", "circular_points_pt1", "consistent_rays", "distortion_field", "fit_conic",
           "fit_homography", "grid_pixels", "hulls_mask", "iac_from_circular_points", "lens_model", "model_valid",
           "observed_field_mask", "rectified_projection", "view_hulls"]
