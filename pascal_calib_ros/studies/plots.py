"""Figures of the experiments (matplotlib, headless)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

PARAMS = (("fu", "f_u"), ("fv", "f_v"), ("u0", "u_0"), ("v0", "v_0"), ("s", "s"))


def _curves(ax: Any, rows: list[dict[str, Any]], key: str, label_of: Any, param: str) -> None:
    groups: dict[str, list[dict[str, Any]]] = {}
    for r in rows:
        groups.setdefault(label_of(r), []).append(r)
    for label, rs in groups.items():
        rs = sorted(rs, key=lambda r: r["sigma"])
        ax.plot([r["sigma"] for r in rs], [r[f"std_{param}"] for r in rs], marker="o", ms=3, label=label)
    ax.set_xlabel("noise sigma (px)")
    ax.set_ylabel(f"std of {key} (px)")
    ax.grid(alpha=0.3)


def plot_experiment(name: str, rows: list[dict[str, Any]], path: Path) -> None:
    if name in ("methods", "layouts", "literal"):
        if name == "methods":
            panels = sorted({r["n_views"] for r in rows})
            fig, axes = plt.subplots(len(panels), 5, figsize=(22, 4.2 * len(panels)), squeeze=False)
            for i, nv in enumerate(panels):
                sub = [r for r in rows if r["n_views"] == nv]
                for j, (p, key) in enumerate(PARAMS):
                    _curves(axes[i][j], sub, f"${key}$", lambda r: r["method"], p)
                    axes[i][j].set_title(f"{nv} views: std of ${key}$")
        else:
            methods = sorted({r["method"] for r in rows})
            fig, axes = plt.subplots(len(methods), 5, figsize=(22, 4.2 * len(methods)), squeeze=False)
            for i, m in enumerate(methods):
                sub = [r for r in rows if r["method"] == m]
                for j, (p, key) in enumerate(PARAMS):
                    _curves(axes[i][j], sub, f"${key}$", lambda r: r["layout"], p)
                    axes[i][j].set_title(f"{m}: std of ${key}$")
                    axes[i][j].set_yscale("symlog", linthresh=0.1)
        for row in axes:
            row[0].legend(fontsize=8)
    else:
        fig, axes = plt.subplots(1, 2, figsize=(13, 4.5), squeeze=False)
        labels = [r["method"] for r in rows]
        if name == "board":
            errs = [abs(r["mean_fu"] / r["true_fu"] - 1) * 100 for r in rows]
            pp = [((r["mean_u0"] - r["true_u0"]) ** 2 + (r["mean_v0"] - r["true_v0"]) ** 2) ** 0.5 for r in rows]
            axes[0][0].bar(labels, errs)
            axes[0][0].set_ylabel("|fu error| (%)")
            axes[0][1].bar(labels, pp)
            axes[0][1].set_ylabel("principal point error (px)")
            axes[0][0].set_yscale("log")
            axes[0][1].set_yscale("log")
        else:
            axes[0][0].bar(labels, [r["mean_parallel_deg"] for r in rows])
            axes[0][0].set_ylabel("mean angle between parallel lines (deg, ideal 0)")
            axes[0][1].bar(labels, [abs(r["mean_perpendicular_deg"] - 90) for r in rows])
            axes[0][1].set_ylabel("|mean angle of perpendicular lines - 90| (deg)")
        for ax in axes[0]:
            ax.grid(alpha=0.3, axis="y")
            ax.tick_params(axis="x", rotation=20)
    fig.suptitle(f"pascal-calib experiment {name}")
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)
