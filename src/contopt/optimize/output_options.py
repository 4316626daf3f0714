"""What a run writes (:class:`OutputOptions`), apart from the driver that imports JAX: reading a
problem file about it (``contopt schema``, ``contopt explain``) loads none."""

from __future__ import annotations

from dataclasses import dataclass

from contopt.errors import ConfigError

#: which iterations get VTU files
VTU_MODES = ("every", "final", "none")
#: the axes a picture can have upwards (None: the direction of the motion)
VIEW_AXES = ("x", "y", "z")


@dataclass(frozen=True)
class OutputOptions:
    """What a run writes besides the checkpoint and history.

    vtu : design and state VTU files for "every" iteration, the "final" one only, or "none"
    view_up : the axis the pictures show upwards, "x", "y" or "z"; None: against the push (the motion)
    plot : redraw ``convergence.png`` after every iteration, and at the end draw the pictures of
        :func:`contopt.optimize.report.make_pictures` (from the final VTU, written even with vtu="none")
    curves : with ``plot``, solve the first and the last design again from zero along the load path for
        ``curves.json`` and its picture (:mod:`contopt.optimize.curves`: two analyses from zero, each
        about the full design's reference analysis); False leaves them out (a benchmark of the loop)

    A run directory always gets ``report.html`` at the end (:mod:`contopt.optimize.report_html`):
    the summary, the pictures there are and a 3D view of the final VTU (none with vtu="none" and
    plot=False).
    """

    vtu: str = "every"
    plot: bool = True
    view_up: str | None = None
    curves: bool = True

    def __post_init__(self):
        if not isinstance(self.curves, bool):
            raise ConfigError(f"output.curves must be true or false, got {self.curves!r}")
        if self.vtu not in VTU_MODES:
            raise ConfigError(f"output.vtu must be one of {VTU_MODES}, got {self.vtu!r}")
        if self.view_up is not None and self.view_up not in VIEW_AXES:
            raise ConfigError(
                f"output.view_up must be one of {VIEW_AXES} or None (from the motion), got {self.view_up!r}"
            )
