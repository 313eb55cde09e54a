"""Pieces of the report's HTML and Markdown: section list, colours, CSS, cells, tables,
embedded figures."""

from __future__ import annotations

import base64
import html
import io
import math
import textwrap
from collections.abc import Sequence
from typing import Any

from hystdisc.registry import family_names, get_family

#: (id, title) of every section, in order; each is an ``<h2 id=...>`` of the HTML.
SECTIONS: tuple[tuple[str, str], ...] = (
    ("summary", "Summary"),
    ("failed", "Failed tasks"),
    ("data", "Data"),
    ("time-series", "Measured and simulated output"),
    ("loops", "Hysteresis loops"),
    ("families", "Family comparison"),
    ("parameters", "Parameters"),
    ("current-laws", "Current laws (staged fit)"),
    ("correspondence", "Term correspondence (seed, section 5)"),
    ("selection", "Term selection (stage 1)"),
    ("closing", "Closing the loop"),
    ("what-to-test-next", "What to test next"),
)

#: Colours of the report's own curves (a family's is its ``color``: :func:`color_of`).
OTHER_COLORS = {"discovered": "tab:brown", "final": "tab:orange"}


def color_of(key: str) -> str | None:
    """The colour of a family's curves (the family declares it), of the discovered
    structure or of the final model; None for anything else.

    Examples
    --------
    >>> color_of("dahl"), color_of("final"), color_of("nothing")
    ('tab:blue', 'tab:orange', None)
    """
    if key in OTHER_COLORS:
        return OTHER_COLORS[key]
    return get_family(key).color if key in family_names() else None


CSS = """
body{font-family:system-ui,-apple-system,"Segoe UI",Helvetica,Arial,sans-serif;margin:0 auto;
max-width:1150px;padding:1em 2em;color:#222;line-height:1.45}
h1{font-size:1.6em;border-bottom:2px solid #444;padding-bottom:.2em}
h2{font-size:1.3em;border-bottom:1px solid #bbb;margin-top:2em;padding-bottom:.15em}
h3{font-size:1.05em;margin-top:1.3em}h3.selected{background:#fff6d8;padding:.15em .4em}
table{border-collapse:collapse;margin:.6em 0;font-size:.9em;display:block;max-width:100%;
overflow-x:auto}
th,td{border:1px solid #ccc;padding:.25em .6em;text-align:right;vertical-align:top}
th{background:#f0f0f0}td.l,th.l{text-align:left}
tr.sel td{background:#fff6d8;font-weight:600}
pre{background:#f6f6f6;padding:.6em;overflow-x:auto;font-size:.88em}
img{max-width:100%;height:auto;display:block;margin:.6em 0}
.note{color:#555;font-size:.9em}.bad{color:#a00}.good{color:#070}
nav{display:flex;flex-wrap:wrap;gap:.2em 1em}code{font-size:.92em}
@media (max-width:800px){body{padding:.5em 1em}}
"""


# ----------------------------------------------------------------------------- helpers


def esc(x: Any) -> str:
    """``x`` as HTML-escaped text."""
    return html.escape(str(x), quote=True)


def num(x: Any, fmt: str = ".4g") -> str:
    """A number formatted with ``fmt``; a dash for None, NaN or inf; other text as is."""
    if x is None:
        return "–"
    try:
        v = float(x)
    except (TypeError, ValueError):
        return str(x)
    if not math.isfinite(v):
        return "–"
    return format(v, fmt)


def ci_text(ci: Any, fmt: str = ".4g") -> str:
    """An interval as ``[low, high]``; a dash when an end is missing."""
    if not ci or len(ci) != 2 or ci[0] is None or ci[1] is None:
        return "–"
    return f"[{num(ci[0], fmt)}, {num(ci[1], fmt)}]"


def md_cell(x: Any) -> str:
    """A Markdown table cell: pipes escaped, one line."""
    return " ".join(str(x).split()).replace("|", "\\|")


def html_table(
    header: Sequence[str], rows: Sequence[Sequence[Any]], left: int | set[int] = 1, sel=None
) -> str:
    """An HTML table; ``left``: the first n columns, or a set of columns, left-aligned (text);
    ``sel``: indices of highlighted rows."""
    sel = set(sel or ())
    lcols = set(range(left)) if isinstance(left, int) else set(left)

    def cls(k: int) -> str:
        return ' class="l"' if k in lcols else ""

    out = ["<table><tr>"]
    out += [f"<th{cls(k)}>{esc(h)}</th>" for k, h in enumerate(header)]
    out.append("</tr>")
    for i, row in enumerate(rows):
        out.append('<tr class="sel">' if i in sel else "<tr>")
        out += [f"<td{cls(k)}>{esc(c)}</td>" for k, c in enumerate(row)]
        out.append("</tr>")
    out.append("</table>")
    return "".join(out)


def md_table(header: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    """A Markdown table."""
    lines = ["| " + " | ".join(md_cell(h) for h in header) + " |"]
    lines.append("|" + "|".join("---" for _ in header) + "|")
    lines += ["| " + " | ".join(md_cell(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def new_figure(
    nrows: int,
    ncols: int,
    width: float,
    height: float,
    layout: str | None = "constrained",
    **kw: Any,
):
    """A figure (not registered with pyplot) and its ``nrows`` x ``ncols`` axes.

    ``layout=None`` leaves the placement to the caller (``fig.subplots_adjust``): the
    constrained layout measures every tick label of every panel, half the drawing time of
    a figure of many panels.
    """
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), layout=layout)
    axes = fig.subplots(nrows, ncols, squeeze=False, **kw)
    return fig, axes


def png(fig, dpi: int) -> str:
    """Render a figure to a base64 ``<img>`` and release it."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    fig.clear()
    data = base64.b64encode(buf.getvalue()).decode("ascii")
    return f'<img src="data:image/png;base64,{data}" alt="figure">'


MAX_POINTS = 2500


def thin(n: int) -> slice:
    """Every k-th sample so that at most MAX_POINTS remain (a figure-only decimation)."""
    return slice(None, None, max(1, math.ceil(n / MAX_POINTS)))


def figure_legend(fig, ax) -> None:
    """One legend for the whole figure, above all its panels, in as many columns as fit."""
    handles, labels = ax.get_legend_handles_labels()
    if labels:
        labels = [textwrap.fill(lab, 40) for lab in labels]  # long discovered structures
        ncols = max(1, min(len(labels), 4))
        fig.legend(handles, labels, loc="outside upper center", fontsize="small", ncols=ncols)


def md_line(text: str) -> str:
    """``text`` on one line."""
    return " ".join(str(text).split())


def currents_text(cs) -> str:
    """The distinct currents of ``cs``, comma-separated."""
    from hystdisc.data import distinct_currents

    return ", ".join(f"{c:g}" for c in distinct_currents(cs))
