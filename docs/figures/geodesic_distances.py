"""Draw the shaping's distances to a maze world's regions, straight and through free space.

    .venv/bin/python docs/figures/geodesic_distances.py [WORLD] [OUT.png]

(default: specs/envs/pointmaze-medium.yaml, docs/figures/pointmaze-medium-distances.png).
Per label (a row) it draws, over the maze, the straight distance the potential measured before
(left) and the geodesic one it measures now (right): the distance that ``e(s, q)`` of
``mitlc/task/potential.py`` reads, from the wrapper's own labels and occupancy
(``mitlc/labels/geodesic.py``). Walls are black; the label's region is outlined in white.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from mitlc.automata import translate
from mitlc.labels.distance import distances
from mitlc.labels.values import NO_MOMENT
from mitlc.syntax import parse
from mitlc.worlds.door import open_world

ROOT = Path(__file__).resolve().parents[2]
STEP = 0.05
"""The spacing of the drawn points, in metres."""


def field(labels: Any, prop: str, key: str, xs: Any, ys: Any, geodesic: Any) -> Any:
    """The distance of every point ``(x, y)`` to where ``prop`` holds."""
    out = np.full((len(ys), len(xs)), np.nan)
    for r, y in enumerate(ys):
        for c, x in enumerate(xs):
            obs = {key: np.array([x, y])}
            found = distances(labels, [prop], obs, {}, NO_MOMENT, geodesic)[0]
            out[r, c] = np.nan if found is None else found
    return out


def main(world_path: Path, out: Path) -> None:
    """Draw the figure of ``world_path`` into ``out``."""
    world = open_world(world_path)
    env = world.task_env(translate(parse(world.spec, world.spec_source)), potential=0.0)
    env.reset(seed=0)
    guide = env._guide
    geodesic = guide.geodesic
    grid = geodesic.occupancy
    labels = env.labels
    (x0, y0), size = grid.origin, grid.cell_size
    nx, ny = grid.shape
    xs = np.arange(x0 + STEP / 2, x0 + nx * size, STEP)
    ys = np.arange(y0 + STEP / 2, y0 + ny * size, STEP)
    walls = np.array([[not grid.free_at((x, y)) for x in xs] for y in ys])
    props = list(world.propositions)
    key = "achieved_goal"
    fig, axes = plt.subplots(len(props), 2, figsize=(9, 4.3 * len(props)), squeeze=False)
    extent = (xs[0] - STEP / 2, xs[-1] + STEP / 2, ys[0] - STEP / 2, ys[-1] + STEP / 2)
    for row, prop in enumerate(props):
        straight = field(labels, prop, key, xs, ys, None)
        through = field(labels, prop, key, xs, ys, geodesic)
        top = float(np.nanmax(np.where(walls, np.nan, through)))
        for col, (values, title) in enumerate(
            [(straight, "straight line (before)"), (through, "through free space (now)")]
        ):
            ax = axes[row][col]
            shown = np.ma.masked_where(walls, values)
            image = ax.imshow(shown, origin="lower", extent=extent, cmap="viridis", vmin=0,
                              vmax=top)  # fmt: skip
            ax.imshow(np.ma.masked_where(~walls, walls), origin="lower", extent=extent,
                      cmap="gray_r", vmin=0, vmax=1)  # fmt: skip
            ax.contour(xs, ys, np.where(walls, np.nan, values), levels=[1e-9], colors="white")
            ax.contour(xs, ys, np.where(walls, np.nan, values), levels=np.arange(1, top, 1),
                       colors="white", linewidths=0.4, alpha=0.6)  # fmt: skip
            ax.set_title(f"distance to {prop}: {title}", fontsize=10)
            ax.set_xticks([])
            ax.set_yticks([])
            fig.colorbar(image, ax=ax, fraction=0.046, pad=0.02, label="m")
    fig.suptitle(f"{world.name}: the shaping's distance e(s, q) to each region", fontsize=11)
    fig.tight_layout()
    fig.savefig(out, dpi=90)
    env.close()


WORLD = ROOT / "specs/envs/pointmaze-medium.yaml"
OUT = ROOT / "docs/figures/pointmaze-medium-distances.png"

if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else WORLD,
         Path(sys.argv[2]) if len(sys.argv) > 2 else OUT)  # fmt: skip
