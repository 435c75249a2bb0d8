"""PNG previews of stored results (matplotlib, Agg canvas; no pyplot, so thread-safe).

- :func:`relief`: one height grid as a shaded relief with a colour bar in mm and a
  scale bar;
- :func:`overview`: several grids side by side on one colour scale, each titled
  (a plan's stages with their tools, an MRR's levels);
- :func:`chain_picture`: arc chains over their input points, corners marked.

Grids larger than :data:`DISPLAY_NODES` a side are reduced by block maxima for
display (a preview never shows a model lower than it is).
"""

from __future__ import annotations

import io
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from matplotlib.colors import LightSource, Normalize
from matplotlib.figure import Figure
from matplotlib.patches import Arc
from mpl_toolkits.axes_grid1.anchored_artists import AnchoredSizeBar
from numpy.typing import NDArray

#: Most nodes a side drawn per grid.
DISPLAY_NODES = 512
_CMAP = "viridis"
_DPI = 100


@dataclass(frozen=True)
class Panel:
    """A grid to draw: heights ``(ny, nx)``, node ``(0, 0)`` at ``(x0, y0)``."""

    z: NDArray[np.float64]
    x0: float
    y0: float
    dx: float
    dy: float
    title: str


def display_grid(z: NDArray[np.float64], max_side: int = DISPLAY_NODES
                 ) -> tuple[NDArray[np.float64], int]:
    """Block maxima of ``z`` so that no side exceeds ``max_side``, and the block size."""
    s = max(1, math.ceil(max(z.shape) / max_side))
    if s == 1:
        return z, 1
    ny, nx = z.shape
    pad = ((0, (-ny) % s), (0, (-nx) % s))
    zp = np.pad(z, pad, mode="edge")
    return zp.reshape(zp.shape[0] // s, s, zp.shape[1] // s, s).max(axis=(1, 3)), s


def _png(fig: Figure) -> bytes:
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(fig)
    out = io.BytesIO()
    # zlib level 3: most of the size of level 6 at a third of its time
    fig.savefig(out, format="png", dpi=_DPI, pil_kwargs={"compress_level": 3})
    return out.getvalue()


def _draw_relief(ax: Any, p: Panel, norm: Normalize, max_side: int = DISPLAY_NODES) -> None:
    z, s = display_grid(p.z, max_side)
    dx, dy = p.dx * s, p.dy * s
    ls = LightSource(azdeg=315, altdeg=45)
    import matplotlib as mpl

    cmap = mpl.colormaps[_CMAP]
    flat = bool(np.ptp(z) <= 1e-9 * max(1.0, float(np.abs(z).max())))
    rgb = cmap(norm(z))[..., :3] if flat else ls.shade(
        z, cmap=cmap, norm=norm, vert_exag=1.0, dx=dx, dy=dy, blend_mode="soft")
    extent = (p.x0 - dx / 2, p.x0 + (z.shape[1] - 0.5) * dx,
              p.y0 - dy / 2, p.y0 + (z.shape[0] - 0.5) * dy)
    ax.imshow(rgb, origin="lower", extent=extent, interpolation="nearest")
    ax.set_title(p.title, fontsize=9)
    ax.set_xlabel("x, mm", fontsize=8)
    ax.set_ylabel("y, mm", fontsize=8)
    ax.tick_params(labelsize=7)
    width = extent[1] - extent[0]
    bar = _nice_length(width / 4)
    ax.add_artist(AnchoredSizeBar(ax.transData, bar, f"{bar:g} mm", "lower right",
                                  pad=0.3, color="black", frameon=True, size_vertical=0,
                                  fontproperties={"size": 7}))


def _nice_length(x: float) -> float:
    """1, 2 or 5 times a power of ten, at most ``x``."""
    if not x > 0:
        return 1.0
    e = math.floor(math.log10(x))
    return max(m * 10.0**e for m in (1, 2, 5) if m * 10.0**e <= x)


def _colour_bar(fig: Figure, axes: Any, norm: Normalize) -> None:
    import matplotlib as mpl
    from matplotlib.cm import ScalarMappable

    bar = fig.colorbar(ScalarMappable(norm=norm, cmap=mpl.colormaps[_CMAP]), ax=axes,
                       shrink=0.85)
    from matplotlib.ticker import ScalarFormatter

    formatter = ScalarFormatter(useOffset=False)  # heights in mm as they are, not offsets
    bar.ax.yaxis.set_major_formatter(formatter)
    bar.set_label("z, mm", fontsize=8)
    bar.ax.tick_params(labelsize=7)


def _norm(panels: Sequence[Panel]) -> Normalize:
    lo = min(float(p.z.min()) for p in panels)
    hi = max(float(p.z.max()) for p in panels)
    # a flat model gets a visible range around its height, not one of rounding noise
    span = max(hi - lo, 1e-3 * max(1.0, abs(hi)), 0.01)
    mid = 0.5 * (lo + hi)
    return Normalize(min(lo, mid - span / 2), max(hi, mid + span / 2))


def relief(panel: Panel) -> bytes:
    """A PNG of one grid: shaded relief, colour bar in mm, scale bar."""
    fig = Figure(figsize=(7.0, 5.6), layout="constrained")
    ax = fig.add_subplot()
    norm = _norm([panel])
    _draw_relief(ax, panel, norm)
    _colour_bar(fig, ax, norm)
    return _png(fig)


def overview(panels: Sequence[Panel], title: str) -> bytes:
    """A PNG of several grids side by side (at most four a row) on one colour scale."""
    cols = min(len(panels), 4)
    rows = math.ceil(len(panels) / cols)
    fig = Figure(figsize=(3.4 * cols + 1.2, 3.4 * rows + 0.7), layout="constrained")
    axes = fig.subplots(rows, cols, squeeze=False)
    norm = _norm(panels)
    for ax, p in zip(axes.flat, panels, strict=False):
        _draw_relief(ax, p, norm, DISPLAY_NODES // 2)  # a panel is about 300 pixels wide
    for ax in list(axes.flat)[len(panels):]:
        ax.set_axis_off()
    _colour_bar(fig, axes, norm)
    fig.suptitle(title, fontsize=10)
    return _png(fig)


def chain_picture(chains: Sequence[Sequence[dict[str, Any]]],
                  points: Sequence[NDArray[np.float64]], corners: Sequence[Sequence[int]],
                  title: str) -> bytes:
    """A PNG of arc chains (segments as in the API) over their input points.

    ``corners[c]`` lists the junctions of chain ``c`` kept sharp (junction ``i`` is the
    end of segment ``i``); they are marked with red crosses, junctions with dots.
    """
    fig = Figure(figsize=(7.0, 6.0), layout="constrained")
    ax = fig.add_subplot()
    ax.set_aspect("equal")
    for pts in points:
        if len(pts):
            ax.plot(pts[:, 0], pts[:, 1], ".", ms=2, color="0.55", zorder=1)
    for c, segments in enumerate(chains):
        for seg in segments:
            _draw_segment(ax, seg)
        ends = np.array([s["end"] for s in segments]) if segments else np.zeros((0, 2))
        if len(ends):
            ax.plot(*np.array(segments[0]["start"]), "o", ms=3, color="k", zorder=3)
            ax.plot(ends[:, 0], ends[:, 1], "o", ms=2.5, color="k", zorder=3)
        sharp = [i for i in (corners[c] if c < len(corners) else []) if 0 <= i < len(ends)]
        if sharp:
            ax.plot(ends[sharp, 0], ends[sharp, 1], "x", ms=8, mew=2, color="red", zorder=4)
    ax.plot([], [], color="tab:blue", label="arc")
    ax.plot([], [], color="tab:orange", label="line")
    ax.plot([], [], "x", color="red", label="corner")
    ax.plot([], [], ".", color="0.55", label="input")
    ax.legend(fontsize=7, loc="best")
    ax.set_title(title, fontsize=9)
    ax.set_xlabel("x, mm", fontsize=8)
    ax.set_ylabel("y, mm", fontsize=8)
    ax.tick_params(labelsize=7)
    ax.autoscale_view()
    return _png(fig)


def _draw_segment(ax: Any, seg: dict[str, Any]) -> None:
    (x0, y0), (x1, y1) = seg["start"], seg["end"]
    if seg["kind"] == "line":
        ax.plot([x0, x1], [y0, y1], color="tab:orange", lw=1.4, zorder=2)
        return
    (cx, cy), r, sweep = seg["center"], seg["radius"], seg["sweep"]
    a0 = math.degrees(math.atan2(y0 - cy, x0 - cx))
    a1 = a0 + math.degrees(sweep)
    lo, hi = (a0, a1) if sweep > 0 else (a1, a0)
    ax.add_patch(Arc((cx, cy), 2 * r, 2 * r, theta1=lo, theta2=hi, color="tab:blue", lw=1.4,
                     zorder=2))
    # patches do not take part in autoscaling: the arc's extreme points do
    t = np.radians(np.linspace(lo, hi, 16))
    ax.update_datalim(np.c_[cx + r * np.cos(t), cy + r * np.sin(t)])
