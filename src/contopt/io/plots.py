"""Plots of an optimization run (matplotlib, headless Agg backend)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from contopt import extras
from contopt.io.files import output_error, write_atomically


def _pyplot():
    extras.require("viz", "the plots need")  # matplotlib
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
    return _save(plt, fig, path)


def pressure_history_figure(iterations, pressures, objective, title: str = ""):
    """The matplotlib Figure of :func:`plot_pressure_history` (the caller closes it).

    Axes 0 holds exactly one line per node (column of ``pressures``), axes 1 the objective.
    """
    plt = _pyplot()
    it = np.asarray(iterations, dtype=np.float64).reshape(-1)
    lam = np.asarray(pressures, dtype=np.float64)
    f = np.asarray(objective, dtype=np.float64).reshape(-1)
    if lam.ndim != 2 or lam.shape[0] != it.size or f.size != it.size:
        raise ValueError(
            f"pressures must be (k, n_nodes) and objective (k,) for k = {it.size} iterations, "
            f"got {lam.shape} and {f.shape}"
        )
    fig, axes = plt.subplots(1, 2, figsize=(11, 4), dpi=100)
    # one Line2D per node: thin and translucent so that thousands of nodes still read as a band
    lw, alpha = (1.0, 0.9) if lam.shape[1] <= 50 else (0.5, 0.4)
    axes[0].plot(it, lam, "-", lw=lw, alpha=alpha)
    axes[0].set(
        xlabel="iteration",
        ylabel=r"nodal contact pressure $\lambda_A$",
        title=f"(a) contact pressures ({lam.shape[1]} nodes)",
    )
    axes[1].plot(it, f, "o-", ms=3, color="k")
    axes[1].set(xlabel="iteration", ylabel=r"$f / |f^0|$", title="(b) normalized objective")
    from matplotlib.ticker import MaxNLocator

    for ax in axes:
        ax.grid(True, alpha=0.3)
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig


def plot_pressure_history(iterations, pressures, objective, path: str | os.PathLike, title: str = "") -> Path:
    """Nodal contact pressures and the normalized objective per iteration as a PNG (written atomically).

    iterations : (k,) optimizer iterations; pressures : (k, n_nodes) nodal contact pressures
    lambda_A of the iterate of each iteration (the nodes of all contact interfaces side by side);
    objective : (k,) normalized objective f / |f^0|. Panel (a) draws one line per node, panel (b)
    the objective.
    """
    plt = _pyplot()
    path = Path(path)
    fig = pressure_history_figure(iterations, pressures, objective, title)
    return _save(plt, fig, path)


def _save(plt, fig, path: Path) -> Path:
    """Write ``fig`` to ``path`` atomically (a viewer never sees half a PNG) and close it.

    A failed write (e.g. a full disk) leaves no temporary and raises :class:`~contopt.errors.OutputError`.
    """
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        return write_atomically(path, fig.savefig)
    except OSError as err:
        raise output_error(path, err) from err
    finally:
        plt.close(fig)


def _abscissa(entry: dict) -> tuple[list, str]:
    """What a curve set's contact forces are drawn against: the first motion's travel, else the load factor."""
    motion = next((m for m in entry.get("motions", []) if m.get("kind") == "motion"), None)
    if motion is None:
        return entry["load_factor"], "load factor t"
    return motion["travel"], f"displacement of {motion['name']}"


def curve_panels(data: dict) -> list[dict]:
    """The panels of :func:`plot_curves`: {title, xlabel, ylabel, lines: [(label, x, y, style)]}.

    One panel per prescribed motion (its force along the motion against its displacement), one for
    the supports (the size of each one's reaction against the load factor) and one for the contact
    interfaces (each one's normal force, and friction force, against the first motion's displacement
    or the load factor, with a load-path objective's ``target`` points); the curve sets of
    ``data["curves"]`` (e.g. the first and the last design) are told apart by the line style.
    """
    entries = data.get("curves", [])
    styles = ("o-", "s--", "^:", "d-.")
    panels: dict[str, dict] = {}

    def add(key, title, xlabel, ylabel, line):
        panels.setdefault(key, {"title": title, "xlabel": xlabel, "ylabel": ylabel, "lines": []})["lines"].append(line)

    for k, entry in enumerate(entries):
        style, tag = styles[k % len(styles)], entry.get("label", f"curve set {k}")
        for m in entry.get("motions", []):
            if m["kind"] == "motion":
                add(
                    m["name"],
                    f"motion {m['name']}",
                    "displacement",
                    "force along the motion",
                    (tag, m["travel"], m["force_along"], style),
                )
            else:
                add(
                    "supports",
                    "supports",
                    "load factor t",
                    "reaction (size)",
                    (f"{m['name']}, {tag}", entry["load_factor"], m["force_size"], style),
                )
        x, xlabel = _abscissa(entry)
        for i in entry.get("interfaces", []):
            add(
                "contact",
                "contact interfaces",
                xlabel,
                "contact force",
                (f"{i['name']} normal, {tag}", x, i["normal_force"], style),
            )
            if "friction_force" in i:
                add(
                    "contact",
                    "contact interfaces",
                    xlabel,
                    "contact force",
                    (f"{i['name']} friction, {tag}", x, i["friction_force"], style),
                )
    target = data.get("target")
    if target and "contact" in panels and entries:  # at the load factors of its points, on the curves' abscissa
        x, _ = _abscissa(entries[0])
        at = np.interp(target["load_factor"], entries[0]["load_factor"], x)
        add("contact", "contact interfaces", "", "", (f"target ({target['name']})", at, target["force"], "k*:"))
    order = [k for k in panels if k not in ("supports", "contact")] + [
        k for k in ("contact", "supports") if k in panels
    ]
    return [panels[k] for k in order]


def plot_curves(data: dict, path: str | os.PathLike) -> Path:
    """Force-displacement curves along the load path (``curves.json``) as a PNG (written atomically);
    the panels of :func:`curve_panels`, three per row. ValueError when there is nothing to draw."""
    panels = curve_panels(data)
    if not panels:
        raise ValueError("the curves hold no prescribed displacement and no contact interface")
    plt = _pyplot()
    cols = min(3, len(panels))
    rows = -(-len(panels) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4.4 * cols, 3.6 * rows), dpi=100, squeeze=False)
    for ax, panel in zip(axes.ravel(), panels):
        for label, x, y, style in panel["lines"]:
            ax.plot(x, y, style, ms=3, label=label)
        ax.set(title=panel["title"], xlabel=panel["xlabel"], ylabel=panel["ylabel"])
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    for ax in axes.ravel()[len(panels) :]:
        ax.set_visible(False)
    fig.tight_layout()
    return _save(plt, fig, Path(path))
