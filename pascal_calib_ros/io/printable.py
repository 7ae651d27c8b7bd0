"""Printable targets at exact scale (PDF, SVG or PNG): the page is the sheet, 1 m = 1 m.

Boards are drawn module by module from the same layout the renderer and the detector use
(:meth:`ModuleLattice.rectangles`): a ChArUco as OpenCV draws it, an AprilGrid as Kalibr does.
Each page carries the target's name, its feature dimensions and a 50 mm scale bar with 10 mm
ticks, so a user can print at 100 %, measure, and correct the YAML if the printer scaled it.
"""

from __future__ import annotations

from pathlib import Path

from ..targets import Target

INCH = 0.0254


def _describe(t: Target) -> str:
    parts = [f"ring r {1000 * r.outer_radius:g}/{1000 * r.inner_radius:g} mm" for r in t.rings]
    parts += [f"disc r {1000 * d.radius:g} mm" for d in t.discs]
    parts += [f"{g.rows}x{g.cols} {g.kind}s r {1000 * g.outer_radius:g}"
              + (f"/{1000 * g.inner_radius:g}" if g.kind == "ring" else "") + f" mm, pitch {1000 * g.pitch:g} mm"
              for g in t.grids]
    parts += [b.describe() for b in t.boards]
    return f"{t.name}: sheet {1000 * t.sheet[0]:g} x {1000 * t.sheet[1]:g} mm; " + ", ".join(parts)


def write_printable(target: Target, path: str | Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle, Rectangle

    p = Path(path)
    if p.suffix.lower() not in (".pdf", ".svg", ".png"):
        raise ValueError(f"output must end in .pdf, .svg or .png, got {p.name!r}")
    w, h = target.sheet
    fig = plt.figure(figsize=(w / INCH, h / INCH))
    ax = fig.add_axes((0.0, 0.0, 1.0, 1.0))
    ax.set_xlim(0, w)
    ax.set_ylim(h, 0)  # y down, as in the target frame
    ax.set_aspect("equal")
    ax.axis("off")
    for r in target.rings:
        ax.add_patch(Circle(r.center, r.outer_radius, color="black", lw=0))
        ax.add_patch(Circle(r.center, r.inner_radius, color="white", lw=0))
    for d in target.discs:
        ax.add_patch(Circle(d.center, d.radius, color="black", lw=0))
    for g in target.grids:
        for x, y in g.centers():
            ax.add_patch(Circle((x, y), g.outer_radius, color="black", lw=0))
            if g.kind == "ring":
                ax.add_patch(Circle((x, y), g.inner_radius, color="white", lw=0))
    for b in target.boards:  # the dark modules of every board: squares, markers, tags
        for lattice in b.lattices():
            for x, y, dx, dy in lattice.rectangles():
                ax.add_patch(Rectangle((x, y), dx, dy, color="black", lw=0, antialiased=False))
    # scale bar (50 mm, ticks every 10 mm) and the description along the bottom edge
    x0, y0 = 0.008, h - 0.006
    ax.plot([x0, x0 + 0.05], [y0, y0], color="black", lw=0.8)
    for k in range(6):
        ax.plot([x0 + 0.01 * k, x0 + 0.01 * k], [y0, y0 - (0.003 if k % 5 == 0 else 0.0015)], color="black", lw=0.6)
    ax.text(x0 + 0.052, y0, "50 mm", fontsize=6, va="center")
    ax.text(x0 + 0.07, y0, _describe(target) + "  - print at 100 %, no scaling", fontsize=6, va="center")
    p.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(p, dpi=300 if p.suffix.lower() == ".png" else 72)
    plt.close(fig)
    return p
