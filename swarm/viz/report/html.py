"""What every report page is built of: figures as inline PNGs, formatted cells, the Jinja2
templates (``swarm/viz/templates``), and the report's error."""

from __future__ import annotations

import base64
import functools
import io
import math
from datetime import UTC, datetime
from typing import Any

from jinja2 import Environment, PackageLoader, StrictUndefined, select_autoescape
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from swarm.errors import SwarmError

ANIMATION_NAMES = ("animation.mp4", "animation.gif")
_DPI = 100
MINUS = "\u2212"  # in "dacmp − greedy"


class ReportError(SwarmError, ValueError):
    """A report cannot be written as asked."""


# --- small helpers ----------------------------------------------------------------------------

def new_figure(w: float, h: float) -> Figure:
    fig = Figure(figsize=(w, h), dpi=_DPI)
    FigureCanvasAgg(fig)
    return fig


def _png_uri(fig: Figure) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=_DPI)
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


def fmt(value: Any) -> str:
    """A table cell's text: numbers short (``0.7423``, ``12``), None and NaN ``–``."""
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        if math.isnan(value):
            return "–"
        if math.isinf(value):
            return "∞" if value > 0 else "−∞"
        if value == int(value) and abs(value) < 1e12:
            return f"{value:.0f}"
        return f"{value:.4g}"
    if value is None:
        return "–"
    return str(value)


def cell(text: Any, cls: str | None = None, title: str | None = None) -> dict[str, Any]:
    """A table cell with a CSS class (``num``: right-aligned) and a tooltip."""
    return {"text": text, "cls": cls, "title": title}


@functools.cache
def _environment() -> Environment:
    env = Environment(
        loader=PackageLoader("swarm.viz", "templates"),
        autoescape=select_autoescape(enabled_extensions=("html.j2", "html"), default_for_string=True, default=True),
        undefined=StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
        keep_trailing_newline=True,
    )
    env.filters["fmt"] = fmt
    return env


def render(template: str, **context: Any) -> str:
    """Render one of the report templates (``run_report.html.j2``, ``sweep_report.html.j2``)."""
    context.setdefault("written", f"{datetime.now(UTC):%Y-%m-%d %H:%M}")
    return _environment().get_template(template).render(**context)


def figure_item(fig: Figure, caption: str, alt: str, width: int | None = None) -> dict[str, Any]:
    return {"uri": _png_uri(fig), "caption": caption, "alt": alt, "width": width}

def as_number(v: Any) -> float:
    try:
        return float(v)
    except (TypeError, ValueError):
        return float("nan")
