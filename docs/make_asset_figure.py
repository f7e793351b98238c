"""Look check for scenes.assets: writes docs/images/assets.png.

Rows: one per kind (isometric, top, front and side orthographic views, flat-shaded, coloured by part role),
plus a bird flap sequence and a quadcopter prop-angle sequence. Run: ``python docs/make_asset_figure.py``.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import PolyCollection  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from scenes.assets import KINDS, ROLES, MeshPart, build_asset  # noqa: E402

SIZES = {"quadcopter": 0.45, "hexacopter": 1.0, "fixed_wing": 2.0, "bird": 0.9, "airliner": 35.0}
ROLE_COLOURS = dict(zip(ROLES, plt.get_cmap("tab20").colors[::2] + plt.get_cmap("tab20").colors[1::2]))

# view direction (camera -> scene) and up vector
VIEWS = {
    "iso": (np.array([-0.55, 0.65, -0.5]), np.array([0.0, 0.0, 1.0])),
    "top": (np.array([0.0, 0.0, -1.0]), np.array([1.0, 0.0, 0.0])),
    "front": (np.array([-1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0])),
    "side": (np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0])),
}
LIGHT = np.array([0.3, 0.4, 1.0]) / np.linalg.norm([0.3, 0.4, 1.0])


def draw(ax: plt.Axes, parts: list[MeshPart], view: str, title: str) -> None:
    """Painter's-algorithm orthographic render with back-face culling and Lambert shading."""
    d, up = VIEWS[view]
    d = d / np.linalg.norm(d)
    right = np.cross(d, up)
    right /= np.linalg.norm(right)
    up2 = np.cross(right, d)
    polys, depth, cols = [], [], []
    for p in parts:
        tri = p.vertices[p.faces]
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        keep = n @ d < 0.0
        tri, n = tri[keep], n[keep]
        shade = 0.45 + 0.55 * np.clip(n @ LIGHT, 0.0, 1.0)
        base = np.array(ROLE_COLOURS[p.role])
        polys.append(np.stack([tri @ right, tri @ up2], axis=-1))
        depth.append((tri @ d).mean(axis=1))
        cols.append(np.clip(base[None] * shade[:, None], 0, 1))
    polys_a, depth_a, cols_a = np.concatenate(polys), np.concatenate(depth), np.concatenate(cols)
    order = np.argsort(-depth_a)
    ax.add_collection(PolyCollection(polys_a[order], facecolors=cols_a[order], edgecolors=cols_a[order],
                                     linewidths=0.2))
    pts = polys_a.reshape(-1, 2)
    lo, hi = pts.min(0), pts.max(0)
    c, r = 0.5 * (lo + hi), 0.55 * (hi - lo).max()
    ax.set_xlim(c[0] - r, c[0] + r)
    ax.set_ylim(c[1] - r, c[1] + r)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_title(title, fontsize=8)


def main() -> Path:
    out = Path(__file__).resolve().parent / "images" / "assets.png"
    out.parent.mkdir(parents=True, exist_ok=True)
    n_rows = len(KINDS) + 2
    fig, axes = plt.subplots(n_rows, 4, figsize=(12, 3 * n_rows))
    for i, kind in enumerate(KINDS):
        parts = build_asset(kind, SIZES[kind])
        n_tri = sum(len(p.faces) for p in parts)
        for j, view in enumerate(VIEWS):
            draw(axes[i, j], parts, view, f"{kind} {SIZES[kind]:g} m, {view}" + (f" ({n_tri} tris)" if j == 0 else ""))
    for j, phase in enumerate((-0.5 * math.pi, 0.0, 0.25 * math.pi, 0.5 * math.pi)):
        draw(axes[-2, j], build_asset("bird", 0.9, flap_phase_rad=phase), "front", f"bird flap phase {phase:.2f} rad")
    for j, ang in enumerate((0.0, 0.4, 0.8, 1.2)):
        draw(axes[-1, j], build_asset("quadcopter", 0.45, rotor_angle_rad=ang), "top",
             f"quadcopter rotor angle {ang:.1f} rad")
    used = sorted({p.role for k in KINDS for p in build_asset(k, 1.0)}, key=ROLES.index)
    fig.legend(handles=[Patch(color=ROLE_COLOURS[r], label=r) for r in used], loc="upper center", ncol=len(used),
               fontsize=8)
    fig.tight_layout(rect=(0, 0, 1, 0.985))
    fig.savefig(out, dpi=90)
    plt.close(fig)
    return out


if __name__ == "__main__":
    print(main())
