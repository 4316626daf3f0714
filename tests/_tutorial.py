"""The tutorial's first set-up (a 16-gon roller, the beam's top nonmortar), which issue 35's Newton
figures (benchmarks/contact_newton.py) and the contact-trust regressions (tests/optimize/
test_contact_trust.py) were found on; the tutorial itself now has a 64-gon roller and lets contopt
choose the sides (docs/tutorial.md)."""

from pathlib import Path

TUTORIAL = Path(__file__).resolve().parents[1] / "examples" / "tutorial.toml"
FIRST_SETUP = (
    ("divisions = [16, 1, 4]", "divisions = [4, 1, 4]"),
    (
        'surfaces = [{ body = "beam", set = "ymax" }, { body = "roller", set = "outer" }]',
        'nonmortar = { body = "beam", set = "ymax" }\nmortar = { body = "roller", set = "outer" }',
    ),
)
PRESS = "value = [0.0, -0.04, 0.0]"  # the roller's motion in the tutorial


def tutorial_text(first: bool = True, press: float | None = None) -> str:
    """examples/tutorial.toml, with the first set-up (``first``) and the roller pressed ``press`` (None: as
    it is); every replaced text must be there (a changed tutorial is an error, not a silent miss)."""
    text = TUTORIAL.read_text(encoding="utf-8")
    edits = (
        *(FIRST_SETUP if first else ()),
        *(((PRESS, f"value = [0.0, {-press!r}, 0.0]"),) if press is not None else ()),
    )
    for old, new in edits:
        if old not in text:
            raise ValueError(f"examples/tutorial.toml has changed: no {old!r} to replace")
        text = text.replace(old, new)
    return text
