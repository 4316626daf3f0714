"""Plots of an optimization run (matplotlib, headless Agg backend)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np


def _pyplot():
    import matplotlib

    matplotlib.use("Agg", force=False)  # headless: never needs a display
    import matplotlib.pyplot as plt

    return plt


def plot_convergence(rows: list[dict], path: str | os.PathLike, title: str = "") -> Path:
    """Objective, constraints and optimality per iteration as a PNG (written atomically).

    ``rows``: history rows with ``iteration``, ``objective`` and the dicts
    ``constraints`` (name -> g, feasible <= 0) and optionally ``optimality``.
    """
    plt = _pyplot()
    path = Path(path)
    it = np.array([r["iteration"] for r in rows])
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.6), dpi=100)
    axes[0].plot(it, [r["objective"] for r in rows], "o-", ms=3)
    axes[0].set(xlabel="iteration", ylabel="objective (scaled)", title="objective")
    names = list(dict.fromkeys(k for r in rows for k in r.get("constraints", {})))
    for name in names:
        axes[1].plot(it, [r.get("constraints", {}).get(name, np.nan) for r in rows], "o-", ms=3, label=name)
    axes[1].axhline(0.0, color="k", lw=0.8)
    axes[1].set(xlabel="iteration", ylabel="g (feasible <= 0)", title="constraints")
    if names:
        axes[1].legend(fontsize=7)
    opt = np.array([r.get("optimality", np.nan) for r in rows], dtype=float)
    change = np.array([r.get("change", np.nan) for r in rows], dtype=float)
    drawn = False
    for values, label in ((opt, "optimality"), (change, "max |dx|")):
        ok = np.isfinite(values) & (values > 0)
        if ok.any():
            axes[2].semilogy(it[ok], values[ok], "o-", ms=3, label=label)
            drawn = True
    axes[2].set(xlabel="iteration", title="convergence")
    if drawn:
        axes[2].legend(fontsize=7)
    for ax in axes:
        ax.grid(True, alpha=0.3)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.stem}.tmp.png")
    fig.savefig(tmp)
    plt.close(fig)
    os.replace(tmp, path)
    return path
