"""Where a target is asked to be: its features' centre on a pixel, at a distance, tilted and
rolled. The guide's candidates (:mod:`..analysis.candidates`) are placements; NEXT.yaml
(:mod:`..io.next_yaml`) writes them for people."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Placement:
    """How a candidate is placed: the features' centre on ``pixel`` at ``distance`` m, tilted by
    ``tilt_deg`` against the line of sight about the in-plane axis at ``axis_deg`` (image
    directions: 0 = right, 90 = down), rolled by ``roll_deg`` about the sheet's normal."""

    pixel: tuple[float, float]
    distance: float
    tilt_deg: float
    axis_deg: float
    roll_deg: float

    def describe(self) -> str:
        """``centre at (u, v) px, d m, tilted a deg about b deg``: for people."""
        return (f"centre at ({self.pixel[0]:.0f}, {self.pixel[1]:.0f}) px, {self.distance:.2f} m, tilted "
                f"{self.tilt_deg:.0f} deg about {self.axis_deg:.0f} deg")


__all__ = ["Placement"]
