"""Geometry without images or ROS: conics and the circular points of a ring (Pascal's theorem), the
image of the absolute conic and K, the lens models behind one interface, the camera, the one pose
type (:class:`Transform`), homographies, regions of an image and where a model holds."""

from .camera import (
    INTRINSIC_BASE,
    Camera,
    calibration_errors,
    pixels_to_normalized,
    project_with_jacobians,
    project_with_point_jacobian,
    rectified_projection,
    rodrigues,
    rotation_to_rvec,
)
from .circular import (
    PT1_STARTS,
    CircularPointError,
    centre_image_from_ring,
    circular_point_pt2,
    circular_points_from_ring,
    circular_points_huang,
    circular_points_pt1,
    pascal_condition,
    vanishing_line_from_centre,
    vanishing_line_huang,
)
from .conic import (
    ConicFitError,
    Ellipse,
    conic_curvature,
    conic_normals,
    conics_from_ellipses,
    ellipse_perimeter,
    ellipses_from_conics,
    fit_conic,
    fit_conics_algebraic,
    group_medians,
    normalize_conic,
    ray_conic_nearest,
    sampson_distance,
    sampson_distances,
)
from .homography import fit_homography
from .iac import DegenerateViewsError, IacSolution, IndefiniteOmegaError, iac_focal_only, iac_from_circular_points
from .image_field import grid_pixels, grid_shape, hulls_mask, observed_field_mask, view_hulls
from .lens import DISTORTION_CHOICES, MODELS, PLUMB_BOB, LensModel, PolynomialModel, lens_model, model_for_coefficients
from .model_field import consistent_rays, distortion_field, model_valid
from .placement import Placement
from .rectify import StereoRectification, horizontal_tangent_rows, rectified_pixels, rectify_maps, rectify_pair
from .so3 import compose_with_jacobians, left_jacobian, skew
from .transform import Transform, TransformError, interpolate

__all__ = ["DISTORTION_CHOICES", "INTRINSIC_BASE", "MODELS", "PLUMB_BOB", "PT1_STARTS", "Camera", "CircularPointError",
           "ConicFitError", "DegenerateViewsError", "Ellipse", "IacSolution", "IndefiniteOmegaError", "LensModel",
           "Placement", "PolynomialModel", "StereoRectification", "Transform", "TransformError", "calibration_errors",
           "centre_image_from_ring", "circular_point_pt2", "circular_points_from_ring", "circular_points_huang",
           "circular_points_pt1", "compose_with_jacobians", "conic_curvature", "conic_normals", "conics_from_ellipses",
           "consistent_rays", "distortion_field", "ellipse_perimeter", "ellipses_from_conics", "fit_conic",
           "fit_conics_algebraic", "fit_homography", "grid_pixels", "grid_shape", "group_medians",
           "horizontal_tangent_rows", "hulls_mask", "iac_focal_only", "iac_from_circular_points", "interpolate",
           "left_jacobian", "lens_model", "model_for_coefficients", "model_valid", "normalize_conic",
           "observed_field_mask", "pascal_condition", "pixels_to_normalized", "project_with_jacobians",
           "project_with_point_jacobian", "ray_conic_nearest", "rectified_pixels", "rectified_projection",
           "rectify_maps", "rectify_pair", "rodrigues", "rotation_to_rvec", "sampson_distance", "sampson_distances",
           "skew", "vanishing_line_from_centre", "vanishing_line_huang", "view_hulls"]
