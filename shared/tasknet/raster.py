"""A raster picture (PNG) of a net, drawn with Pillow from the same layout and arc curves as the
SVG of ``shared.tasknet.layout``: places as circles with their token count (shaded when
marked), transitions as bars, arcs as curves with an arrow head and their weight when it is not
1, ids above the nodes and the predicate or action below them.

The picture is returned as bytes; writing it anywhere is the caller's business.
"""

from __future__ import annotations

import io

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from shared.tasknet.layout import BAR_H, BAR_W, RADIUS, arc_geometry, canvas_size, layered_positions
from shared.tasknet.ptnet import PTNet

INK = (51, 51, 51)
GREY = (85, 85, 85)
MARKED = (255, 233, 168)
WHITE = (255, 255, 255)
ARROW_LEN, ARROW_HALF = 9.0, 4.5


def net_to_png(net: PTNet, marking: np.ndarray | None = None, scale: float = 1.5) -> bytes:
    """PNG bytes of ``net`` showing ``marking`` (M0 when None), ``scale`` pixels per SVG unit."""
    if scale <= 0:
        raise ValueError(f"scale must be positive; got {scale}")
    m = net.m0 if marking is None else net.marking(marking)
    pos = layered_positions(net)
    width, height = canvas_size(pos)
    image = Image.new("RGB", (max(1, round(width * scale)), max(1, round(height * scale))), WHITE)
    draw = ImageDraw.Draw(image)
    font = ImageFont.load_default(size=max(8, round(12 * scale)))
    bold = ImageFont.load_default(size=max(8, round(13 * scale)))
    line = max(1, round(1.5 * scale))

    def px(x: float, y: float) -> tuple[float, float]:
        return x * scale, y * scale

    def text(x: float, y: float, s: str, fill=INK, f=font) -> None:
        # anchored at the middle of the text's baseline, as SVG's text-anchor="middle"
        draw.text(px(x, y), s, fill=fill, font=f, anchor="ms")

    for g in arc_geometry(net, pos):
        points = [px(x, y) for x, y in g.points()]
        draw.line(points, fill=INK, width=max(1, round(scale)))
        # the arrow head along the curve's last tangent (towards the target's outline)
        ux, uy = g.ex - g.cx, g.ey - g.cy
        d = float(np.hypot(ux, uy)) or 1.0
        ux, uy = ux / d, uy / d
        bx, by = g.ex - ARROW_LEN * ux, g.ey - ARROW_LEN * uy
        head = [px(g.ex, g.ey), px(bx - ARROW_HALF * uy, by + ARROW_HALF * ux), px(bx + ARROW_HALF * uy, by - ARROW_HALF * ux)]
        draw.polygon(head, fill=INK)
        if g.arc.weight != 1:
            mx, my = g.weight_at
            text(mx, my + 4, str(g.arc.weight))
    for i, p in enumerate(net.places):
        x, y = pos[p.id]
        tokens = int(m[i])
        box = [*px(x - RADIUS, y - RADIUS), *px(x + RADIUS, y + RADIUS)]
        draw.ellipse(box, fill=MARKED if tokens else WHITE, outline=INK, width=line)
        if tokens:
            text(x, y + 4, str(tokens), f=bold)
        text(x, y - RADIUS - 6, p.id)
        if p.predicate:
            text(x, y + RADIUS + 14, p.predicate, fill=GREY)
        if p.capacity:
            draw.text(px(x + RADIUS + 4, y - RADIUS), f"K={p.capacity}", fill=GREY, font=font, anchor="ls")
    for t in net.transitions:
        x, y = pos[t.id]
        draw.rectangle([*px(x - BAR_W / 2, y - BAR_H / 2), *px(x + BAR_W / 2, y + BAR_H / 2)], fill=INK)
        text(x, y - BAR_H / 2 - 6, t.id)
        if t.action:
            text(x, y + BAR_H / 2 + 14, t.action, fill=GREY)
    out = io.BytesIO()
    image.save(out, format="PNG", optimize=True)
    return out.getvalue()
