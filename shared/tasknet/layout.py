"""A picture of a net: a layered layout of its own and an SVG of it.

Layers are breadth-first distances along arcs from the initially marked places (from the
first place when none is marked; unreached nodes start new layers). Layers run left to right,
nodes of a layer top to bottom. Places are circles with their token count, transitions are
bars, arcs are arrows with their weight when it is not 1 (bent when they
run back or have a twin the other way); capacities show as K=n; ids sit beside the nodes, with the
predicate or action under them when there is one.
"""

from __future__ import annotations

from collections.abc import Sequence

from collections import deque
from dataclasses import dataclass
from html import escape

import numpy as np

from shared.tasknet.ptnet import Arc, PTNet

GAP_X = 170.0
GAP_Y = 90.0
RADIUS = 18.0
BAR_W, BAR_H = 10.0, 40.0
MARGIN = 90.0


def layered_positions(net: PTNet) -> dict[str, tuple[float, float]]:
    """Node id to (x, y) in SVG units (y grows downwards)."""
    succ: dict[str, list[str]] = {n.id: [] for n in (*net.places, *net.transitions)}
    for a in net.arcs:
        succ[a.source].append(a.target)
    order = [n.id for n in (*net.places, *net.transitions)]
    layer: dict[str, int] = {}
    starts = [p.id for p in net.places if p.initial] or order[:1]
    next_layer = 0
    while len(layer) < len(order):
        if not starts:
            starts = [next(n for n in order if n not in layer)]
        queue = deque()
        for s in starts:
            layer[s] = next_layer
            queue.append(s)
        while queue:
            n = queue.popleft()
            for m in succ[n]:
                if m not in layer:
                    layer[m] = layer[n] + 1
                    queue.append(m)
        next_layer = max(layer.values()) + 1
        starts = []
    rows: dict[int, int] = {}
    pos: dict[str, tuple[float, float]] = {}
    for n in order:
        k = layer[n]
        pos[n] = (MARGIN + k * GAP_X, MARGIN + rows.get(k, 0) * GAP_Y)
        rows[k] = rows.get(k, 0) + 1
    return pos


PLANNED_FILL = "#1e88e5"
"""The transitions of a planned path (``net_to_svg``'s ``planned``)."""


def net_to_svg(net: PTNet, marking: np.ndarray | None = None, planned: Sequence[str] = ()) -> str:
    """An SVG document of ``net`` showing ``marking`` (M0 when None); marked places are shaded.
    ``planned``: a path of actions (transition labels) in order; their transitions are drawn in
    blue and numbered in the order the path takes them."""
    step = {}
    for k, action in enumerate(planned, start=1):
        step.setdefault(action, k)
    m = net.m0 if marking is None else net.marking(marking)
    pos = layered_positions(net)
    width, height = canvas_size(pos)
    out = [
        (
            f'<svg xmlns="http://www.w3.org/2000/svg" width="{width:.0f}" height="{height:.0f}" '
            f'viewBox="0 0 {width:.0f} {height:.0f}" font-family="sans-serif" font-size="12">'
        ),
        f"<title>{escape(net.name or net.id)}</title>",
        (
            '<defs><marker id="arrow" viewBox="0 0 10 10" refX="10" refY="5" markerWidth="7" markerHeight="7" '
            'orient="auto-start-reverse"><path d="M0,0 L10,5 L0,10 z" fill="#333"/></marker></defs>'
        ),
    ]
    for g in arc_geometry(net, pos):
        a = g.arc
        out.append(
            f'<path class="arc" data-source="{escape(a.source)}" data-target="{escape(a.target)}" '
            f'd="M{g.sx:.1f},{g.sy:.1f} Q{g.cx:.1f},{g.cy:.1f} {g.ex:.1f},{g.ey:.1f}" fill="none" stroke="#333" '
            'marker-end="url(#arrow)"/>'
        )
        if a.weight != 1:
            mx, my = g.weight_at
            out.append(f'<text class="weight" x="{mx:.1f}" y="{my + 4:.1f}" text-anchor="middle">{a.weight}</text>')
    for i, p in enumerate(net.places):
        x, y = pos[p.id]
        tokens = int(m[i])
        fill = "#ffe9a8" if tokens else "#ffffff"
        out.append(
            f'<g class="place" data-id="{escape(p.id)}" data-tokens="{tokens}">'
            f'<circle cx="{x:.1f}" cy="{y:.1f}" r="{RADIUS}" fill="{fill}" stroke="#333" stroke-width="1.5"/>'
            + (f'<text x="{x:.1f}" y="{y + 4:.1f}" text-anchor="middle" font-weight="bold">{tokens}</text>' if tokens else "")
            + f'<text x="{x:.1f}" y="{y - RADIUS - 6:.1f}" text-anchor="middle">{escape(p.id)}</text>'
            + _label(x, y + RADIUS + 14, p.predicate)
            + (f'<text x="{x + RADIUS + 4:.1f}" y="{y - RADIUS:.1f}" fill="#555">K={p.capacity}</text>' if p.capacity else "")
            + "</g>"
        )
    for t in net.transitions:
        x, y = pos[t.id]
        k = step.get(t.action) if t.action else None
        out.append(
            f'<g class="transition" data-id="{escape(t.id)}"' + (f' data-planned="{k}"' if k else "") + ">"
            f'<rect x="{x - BAR_W / 2:.1f}" y="{y - BAR_H / 2:.1f}" width="{BAR_W}" height="{BAR_H}" '
            f'fill="{PLANNED_FILL if k else "#333"}"/>'
            f'<text x="{x:.1f}" y="{y - BAR_H / 2 - 6:.1f}" text-anchor="middle">{escape(t.id)}'
            + (f" ({k})" if k else "") + "</text>"
            + _label(x, y + BAR_H / 2 + 14, t.action)
            + "</g>"
        )
    out.append("</svg>")
    return "\n".join(out) + "\n"


@dataclass(frozen=True)
class ArcGeometry:
    """One arc drawn as a quadratic curve: from (sx, sy) on the source's outline through the
    control point (cx, cy) to (ex, ey) on the target's outline."""

    arc: Arc
    sx: float
    sy: float
    cx: float
    cy: float
    ex: float
    ey: float
    nx: float  # the left normal of the straight source-target line
    ny: float

    @property
    def weight_at(self) -> tuple[float, float]:
        """Where the weight is written: the curve's midpoint, nudged off the line."""
        return ((self.sx + 2 * self.cx + self.ex) / 4 + 9 * self.nx, (self.sy + 2 * self.cy + self.ey) / 4 + 9 * self.ny)

    def points(self, n: int = 16) -> list[tuple[float, float]]:
        """The curve sampled at ``n + 1`` points, source to target."""
        t = np.linspace(0.0, 1.0, n + 1)
        x = (1 - t) ** 2 * self.sx + 2 * (1 - t) * t * self.cx + t**2 * self.ex
        y = (1 - t) ** 2 * self.sy + 2 * (1 - t) * t * self.cy + t**2 * self.ey
        return list(zip(x.tolist(), y.tolist()))


def arc_geometry(net: PTNet, pos: dict[str, tuple[float, float]]) -> list[ArcGeometry]:
    """Each arc's curve: an arc with a reverse twin, or one running back along the layers,
    bends to its left so that it does not lie on another."""
    places = {p.id for p in net.places}
    pairs = {(a.source, a.target) for a in net.arcs}
    out = []
    for a in net.arcs:
        (x0, y0), (x1, y1) = pos[a.source], pos[a.target]
        d = float(np.hypot(x1 - x0, y1 - y0)) or 1.0
        nx, ny = -(y1 - y0) / d, (x1 - x0) / d
        bend = 0.0
        if (a.target, a.source) in pairs:
            bend = 18.0
        elif x1 < x0 or (x1 == x0 and y1 < y0):
            bend = max(30.0, 0.2 * d)
        cx, cy = (x0 + x1) / 2 + bend * nx, (y0 + y1) / 2 + bend * ny
        sx, sy = _edge(x0, y0, *_unit(cx - x0, cy - y0), a.source in places)
        ex, ey = _edge(x1, y1, *_unit(cx - x1, cy - y1), a.target in places)
        out.append(ArcGeometry(a, sx, sy, cx, cy, ex, ey, nx, ny))
    return out


def canvas_size(pos: dict[str, tuple[float, float]]) -> tuple[float, float]:
    """The picture's width and height for the node positions ``pos``."""
    width = max((x for x, _ in pos.values()), default=0.0) + MARGIN + 80
    height = max((y for _, y in pos.values()), default=0.0) + MARGIN + 30
    return width, height


def _edge(x: float, y: float, ux: float, uy: float, is_place: bool) -> tuple[float, float]:
    """Where a ray from a node's centre along (ux, uy) leaves the node's outline."""
    if is_place:
        return x + RADIUS * ux, y + RADIUS * uy
    sx = (BAR_W / 2) / abs(ux) if ux else np.inf
    sy = (BAR_H / 2) / abs(uy) if uy else np.inf
    s = min(sx, sy)
    return x + s * ux, y + s * uy


def _unit(dx: float, dy: float) -> tuple[float, float]:
    d = float(np.hypot(dx, dy)) or 1.0
    return dx / d, dy / d


def _label(x: float, y: float, text: str | None) -> str:
    if not text:
        return ""
    return f'<text class="label" x="{x:.1f}" y="{y:.1f}" text-anchor="middle" fill="#555">{escape(text)}</text>'
