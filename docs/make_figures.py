"""Draw one figure per information-sharing scheme: what critic i sees, read from the real extractor classes.

For every scheme the script builds the scheme's :class:`~sb3_maddpg.sharing.CriticFeaturesExtractor`
for agent ``i`` of a five-agent team, feeds it a joint observation and a joint action whose entries are
unique tags, and reads back from its output which agent's observation or action sits at which
position of critic i's input. The figures therefore show what the code does, in the order it does it.
For the selected scheme, the selection comes from :class:`~sb3_maddpg.common.selection.NearestAgents` (k=2)
on the positions drawn in the figure.

Usage::

    python docs/make_figures.py           # (re)write docs/_static/schemes/*.svg
    python docs/make_figures.py --check   # exit 1 if a committed figure differs from the code
"""

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path
from xml.sax.saxutils import escape

import numpy as np

OUT_DIR = Path(__file__).resolve().parent / "_static" / "schemes"

N_AGENTS = 5
OWN = 2  # whose critic the figures show
OBS_SIZE, ACTION_SIZE = 4, 2  # [velocity (2), position (2)] is enough for NearestAgents
POSITIONS = np.array([[-0.75, 0.55], [0.55, 0.7], [-0.05, 0.05], [0.5, -0.45], [-0.75, -0.6]])
"""Where the agents stand in the drawing (and in the observation NearestAgents reads)."""

SCHEMES = [
    ("independent", "IDDPG", "its own observation and action only"),
    ("full", "MADDPG", "every observation and every action"),
    ("observations", "MADDPG-fo", "every observation, and its own action only"),
    ("actions", "MADDPG-fa", "its own observation only, and every action"),
    ("selected", "MADDPG-soa", "its own and its k = 2 nearest agents' observations and actions"),
]

OBS_COLOR, ACT_COLOR, OFF_COLOR, OWN_COLOR = "#3b75af", "#ef8636", "#e9e9e9", "#222222"


@dataclass(frozen=True)
class Seen:
    """What one critic sees: its input as a list of (kind, agent) blocks in order, and the selection if any."""

    blocks: tuple[tuple[str, int], ...]
    selection: tuple[int, ...]


def probe(scheme: str) -> Seen:
    """
    Run the scheme's extractor for agent ``OWN`` on tagged inputs and decode its output.

    :param scheme: A scheme name of :data:`sb3_maddpg.sharing.SHARING_SCHEMES`.
    :return: The blocks critic ``OWN`` sees, in input order.
    """
    import torch as th

    from sb3_maddpg.common.layout import AgentLayout
    from sb3_maddpg.common.selection import NearestAgents
    from sb3_maddpg.sharing import resolve_scheme

    layout = AgentLayout(
        agent_ids=tuple(f"agent_{j}" for j in range(N_AGENTS)),
        obs_sizes=(OBS_SIZE,) * N_AGENTS,
        action_sizes=(ACTION_SIZE,) * N_AGENTS,
        position_slices=(slice(2, 4),) * N_AGENTS,  # MPE's layout, as simple_spread declares it
    )
    extractor_class = resolve_scheme(scheme)
    selector = NearestAgents(k=2) if extractor_class.uses_selection else None
    extractor = extractor_class(layout, OWN, selection_size=selector.k if selector else 0)

    # Tags: observation entry d of the joint vector holds 1000 + d, action entry d holds 2000 + d.
    observations = th.arange(layout.obs_dim, dtype=th.float64)[None] + 1000
    actions = th.arange(layout.action_dim, dtype=th.float64)[None] + 2000
    selection_tensor = None
    selection: tuple[int, ...] = ()
    if selector is not None:
        raw = np.zeros((1, layout.obs_dim))
        for j, sl in enumerate(layout.obs_slices):
            raw[0, sl][2:4] = POSITIONS[j]
        chosen = selector.select(raw, layout)
        selection = tuple(int(j) for j in chosen[0, OWN])
        selection_tensor = th.as_tensor(chosen)
    extractor = extractor.double()
    with th.no_grad():
        features = extractor(observations, actions, selection_tensor)[0].tolist()
    if len(features) != extractor.features_dim:
        raise RuntimeError(f"{scheme}: output length {len(features)} != features_dim {extractor.features_dim}")

    blocks: list[tuple[str, int]] = []
    position = 0
    while position < len(features):
        tag = round(features[position])
        kind, index = ("o", tag - 1000) if tag < 2000 else ("a", tag - 2000)
        size = OBS_SIZE if kind == "o" else ACTION_SIZE
        agent, offset = divmod(index, size)
        expected = [tag - offset + d for d in range(size)]
        if offset != 0 or [round(v) for v in features[position : position + size]] != expected:
            raise RuntimeError(f"{scheme}: the critic input is not a concatenation of whole o_j / a_j blocks")
        blocks.append((kind, agent))
        position += size
    return Seen(tuple(blocks), selection)


def _text(
    x: float, y: float, text: str, size: int = 13, anchor: str = "middle", weight: str = "normal", fill: str = "#222"
) -> str:
    return (
        f'<text x="{x:.1f}" y="{y:.1f}" font-size="{size}" text-anchor="{anchor}" font-weight="{weight}" '
        f'fill="{fill}">{escape(text)}</text>'
    )


def _sub(x: float, y: float, kind: str, agent: int, size: int = 14, fill: str = "#fff", weight: str = "normal") -> str:
    """``o_j`` / ``a_j`` with a subscript."""
    return (
        f'<text x="{x:.1f}" y="{y:.1f}" font-size="{size}" text-anchor="middle" font-style="italic" '
        f'font-weight="{weight}" fill="{fill}">{kind}<tspan font-size="{size * 0.7:.1f}" dy="4">{agent}</tspan></text>'
    )


def draw(scheme: str, paper_name: str, description: str, seen: Seen) -> str:
    """
    The SVG of one scheme: the team (left), a seen/not-seen grid (middle) and critic i's input order (bottom).

    :return: The SVG document.
    """
    width, height = 640, 320
    obs_seen = {agent for kind, agent in seen.blocks if kind == "o"}
    act_seen = {agent for kind, agent in seen.blocks if kind == "a"}
    parts = [
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" viewBox="0 0 {width} {height}" '
        'font-family="DejaVu Sans, Arial, Helvetica, sans-serif">',
        f"<title>{escape(f'{scheme} ({paper_name}): what critic {OWN} sees')}</title>",
        f'<rect x="0" y="0" width="{width}" height="{height}" fill="#ffffff"/>',
        _text(12, 24, f'critic_sharing="{scheme}"  ({paper_name})', size=15, anchor="start", weight="bold"),
        _text(12, 44, f"critic {OWN} sees {description}", size=13, anchor="start", fill="#444"),
    ]

    # Left: the team in the plane; agent OWN dark, the others coloured by what its critic sees of them.
    cx, cy, scale = 120, 172, 85
    parts.append(f'<rect x="{cx - 110}" y="{cy - 100}" width="220" height="200" rx="8" fill="#fafafa" stroke="#cccccc"/>')
    parts.append(_text(cx, cy + 118, "the team (2-D plane)", size=12, fill="#555"))
    own_xy = (cx + scale * POSITIONS[OWN][0], cy - scale * POSITIONS[OWN][1])
    for rank, agent in enumerate(seen.selection, start=1):
        x, y = cx + scale * POSITIONS[agent][0], cy - scale * POSITIONS[agent][1]
        parts.append(
            f'<line x1="{own_xy[0]:.1f}" y1="{own_xy[1]:.1f}" x2="{x:.1f}" y2="{y:.1f}" stroke="#777" '
            'stroke-width="1.5" stroke-dasharray="5,3"/>'
        )
        parts.append(_text((own_xy[0] + x) / 2 + 8, (own_xy[1] + y) / 2 - 4, f"s{rank}", size=11, fill="#555"))
    for agent in range(N_AGENTS):
        x, y = cx + scale * POSITIONS[agent][0], cy - scale * POSITIONS[agent][1]
        if agent == OWN:
            parts.append(f'<circle cx="{x:.1f}" cy="{y:.1f}" r="17" fill="{OWN_COLOR}"/>')
        else:
            # Left half: observation seen?  Right half: action seen?
            left = OBS_COLOR if agent in obs_seen else OFF_COLOR
            right = ACT_COLOR if agent in act_seen else OFF_COLOR
            parts.append(f'<path d="M {x:.1f} {y - 17:.1f} A 17 17 0 0 0 {x:.1f} {y + 17:.1f} Z" fill="{left}"/>')
            parts.append(f'<path d="M {x:.1f} {y - 17:.1f} A 17 17 0 0 1 {x:.1f} {y + 17:.1f} Z" fill="{right}"/>')
            parts.append(f'<circle cx="{x:.1f}" cy="{y:.1f}" r="17" fill="none" stroke="#888"/>')
        fill = "#fff" if agent == OWN or agent in obs_seen | act_seen else "#333"
        parts.append(_text(x, y + 5, str(agent), size=14, weight="bold", fill=fill))

    # Middle: the grid of what critic OWN sees, one column per agent.
    gx, gy, cell = 270, 92, 46
    parts.append(_text(gx + cell * N_AGENTS / 2, gy - 10, f"what critic {OWN} sees", size=12, fill="#555"))
    parts.append(_text(gx - 6, gy + 2 * cell + 16, "agent", size=11, anchor="end", fill="#555"))
    for agent in range(N_AGENTS):
        parts.append(_text(gx + cell * agent + cell / 2, gy + 2 * cell + 16, str(agent), size=11, fill="#555"))
        for row, (kind, seen_set, color) in enumerate((("o", obs_seen, OBS_COLOR), ("a", act_seen, ACT_COLOR))):
            on = agent in seen_set
            x, y = gx + cell * agent, gy + cell * row
            stroke = f'stroke="{OWN_COLOR}" stroke-width="3"' if agent == OWN else 'stroke="#ffffff" stroke-width="2"'
            fill = color if on else OFF_COLOR
            size = cell - 4
            parts.append(f'<rect x="{x + 2}" y="{y + 2}" width="{size}" height="{size}" rx="4" fill="{fill}" {stroke}/>')
            parts.append(_sub(x + cell / 2, y + cell / 2 + 3, kind, agent, fill="#fff" if on else "#999"))
    lx = gx + cell * N_AGENTS + 16
    for row, (label, color) in enumerate((("observation", OBS_COLOR), ("action", ACT_COLOR), ("not seen", OFF_COLOR))):
        parts.append(f'<rect x="{lx}" y="{gy + 8 + 24 * row}" width="14" height="14" rx="2" fill="{color}"/>')
        parts.append(_text(lx + 20, gy + 20 + 24 * row, label, size=11, anchor="start", fill="#444"))
    own_box = f'<rect x="{lx}" y="{gy + 80}" width="14" height="14" rx="2" fill="none" stroke="{OWN_COLOR}" stroke-width="3"/>'
    parts.append(own_box)
    parts.append(_text(lx + 20, gy + 92, f"own (agent {OWN})", size=11, anchor="start", fill="#444"))

    # Bottom: critic OWN's input vector, blocks in the order the extractor concatenates them.
    parts.append(_text(gx, 256, f"critic input x_{OWN}, in order:", size=12, anchor="start", fill="#555"))
    bx, by, bh = gx, 266, 30
    block_w = min(36, (width - gx - 12) / max(len(seen.blocks), 1))
    for n, (kind, agent) in enumerate(seen.blocks):
        x = bx + n * block_w
        color = OBS_COLOR if kind == "o" else ACT_COLOR
        stroke = f'stroke="{OWN_COLOR}" stroke-width="3"' if agent == OWN else 'stroke="#ffffff" stroke-width="1.5"'
        parts.append(f'<rect x="{x:.1f}" y="{by}" width="{block_w - 2:.1f}" height="{bh}" rx="3" fill="{color}" {stroke}/>')
        parts.append(_sub(x + block_w / 2 - 1, by + bh / 2 + 4, kind, agent, size=13))
    parts.append("</svg>")
    return "\n".join(parts) + "\n"


def draw_overview(seen_by_scheme: dict[str, Seen]) -> str:
    """
    The five schemes side by side: for each, which observations (top row) and actions (bottom row) critic ``OWN`` sees.

    :return: The SVG document.
    """
    cell, panel_w = 26, 152
    width, height = 20 + panel_w * len(SCHEMES), 150
    parts = [
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" viewBox="0 0 {width} {height}" '
        'font-family="DejaVu Sans, Arial, Helvetica, sans-serif">',
        f"<title>{escape(f'What critic {OWN} sees under each scheme')}</title>",
        f'<rect x="0" y="0" width="{width}" height="{height}" fill="#ffffff"/>',
    ]
    for n, (scheme, paper_name, _) in enumerate(SCHEMES):
        seen = seen_by_scheme[scheme]
        obs_seen = {agent for kind, agent in seen.blocks if kind == "o"}
        act_seen = {agent for kind, agent in seen.blocks if kind == "a"}
        x0 = 20 + n * panel_w
        parts.append(_text(x0 + cell * N_AGENTS / 2, 22, paper_name, size=13, weight="bold"))
        parts.append(_text(x0 + cell * N_AGENTS / 2, 40, f'"{scheme}"', size=11, fill="#555"))
        for agent in range(N_AGENTS):
            for row, (kind, seen_set, color) in enumerate((("o", obs_seen, OBS_COLOR), ("a", act_seen, ACT_COLOR))):
                on = agent in seen_set
                x, y = x0 + cell * agent, 52 + cell * row
                stroke = f'stroke="{OWN_COLOR}" stroke-width="2.5"' if agent == OWN else 'stroke="#ffffff" stroke-width="1.5"'
                size = cell - 3
                fill = color if on else OFF_COLOR
                box = f'x="{x + 1.5}" y="{y + 1.5}" width="{size}" height="{size}"'
                parts.append(f'<rect {box} rx="3" fill="{fill}" {stroke}/>')
                parts.append(_sub(x + cell / 2, y + cell / 2 + 3, kind, agent, size=11, fill="#fff" if on else "#999"))
            parts.append(_text(x0 + cell * agent + cell / 2, 52 + 2 * cell + 14, str(agent), size=10, fill="#777"))
        extra = f"k = {len(seen.selection)} nearest: {', '.join(map(str, seen.selection))}" if seen.selection else ""
        parts.append(_text(x0 + cell * N_AGENTS / 2, 136, extra, size=10, fill="#555"))
    parts.append("</svg>")
    return "\n".join(parts) + "\n"


def render_all() -> dict[str, str]:
    """
    :return: The SVG text of every figure, by file name.
    """
    seen = {scheme: probe(scheme) for scheme, _, _ in SCHEMES}
    figures = {f"{scheme}.svg": draw(scheme, paper, description, seen[scheme]) for scheme, paper, description in SCHEMES}
    figures["overview.svg"] = draw_overview(seen)
    return figures


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="compare with the committed figures instead of writing them")
    args = parser.parse_args(argv)
    figures = render_all()
    if args.check:
        stale = [
            name for name, svg in figures.items() if not (OUT_DIR / name).is_file() or (OUT_DIR / name).read_text() != svg
        ]
        if stale:
            print(f"Out of date: {', '.join(stale)}. Run: python docs/make_figures.py", file=sys.stderr)
            return 1
        print(f"{len(figures)} scheme figures match the code.")
        return 0
    OUT_DIR.mkdir(parents=True, exist_ok=True)
    for name, svg in figures.items():
        (OUT_DIR / name).write_text(svg)
        print(f"wrote {OUT_DIR / name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
