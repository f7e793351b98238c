"""How a sequence is cut into Mitsuba launches: tiles (regions of interest or whole frames), batches
of frames per launch, and where each frame's copy of the world sits in the batched scene.

Pure numpy, no Mitsuba: every choice here is a function of the scene (resolution, projected target
sizes, ranges) and the recorded settings below, never of the machine, so the sample pattern, and
therefore every output byte, is the same on any machine and for any number of workers.

- A *tile* is a sub-sensor of Mitsuba's ``batch`` sensor: a rectangle of one camera's image, cut
  with the same pixel grid (off-axis perspective: film of the tile size, the full image's focal
  length, the principal point shifted to the tile).
- ROI mode: one fixed-size tile per (frame, target), centred on the target; the rest of the frame
  is the sky, evaluated at pixel centres. Used when the tiles cover at most ``ROI_MAX_FRACTION`` of
  the frame; otherwise each frame is one tile (full mode).
- A *batch* is ``batch_frames`` consecutive frames rendered in one launch; frame ``i`` sits in slot
  ``i % batch_frames`` of batch ``i // batch_frames``, so the random numbers a pixel gets depend only
  on its batch, slot and position, not on which other frames share the launch.
- Slot ``s`` holds its frame's world translated so that the camera sits at ``slot_offset(s)``;
  slots are ``slot_spacing_m`` apart, more than a primary ray (clipped at ``far_clip_m``) can reach.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

BATCH_FRAMES = 16            # recorded dataset setting: frames per launch (fixed default)
BATCH_PIXEL_BUDGET = 1 << 21  # at most this many tile pixels per launch (memory bound, scene-derived)
ROI_MARGIN_PX = 3            # tile margin around the projected silhouette box
ROI_ALIGN_PX = 8             # tile sizes are multiples of this
ROI_MAX_FRACTION = 0.35      # ROI mode only while the tiles cover at most this share of a frame
COVERAGE_SUBSAMPLES = 8      # coverage rays per pixel per axis (8 x 8 = 64, regular grid)
NEAR_CLIP_M = 0.1


@dataclass(frozen=True)
class Tile:
    """One sub-sensor: the image rectangle [x0, x0 + width) x [y0, y0 + height) of a camera."""

    x0: int
    y0: int
    width: int
    height: int

    def principal_point_offset(self, image_width: int, image_height: int) -> tuple[float, float]:
        """Mitsuba's principal_point_offset_x/y (in tile widths/heights) that cut this tile out."""
        return (((self.x0 + self.width / 2) - image_width / 2) / self.width,
                ((self.y0 + self.height / 2) - image_height / 2) / self.height)


@dataclass(frozen=True)
class CameraPlan:
    """The launch layout of one camera over a sequence."""

    mode: str                  # "roi" or "full"
    tile_width: int
    tile_height: int
    tiles_per_frame: int       # n targets in ROI mode, 1 in full mode
    batch_frames: int
    far_clip_m: float
    slot_spacing_m: float

    @property
    def tiles_per_batch(self) -> int:
        return self.tiles_per_frame * self.batch_frames

    def slot_offset_m(self, slot: int) -> np.ndarray:
        """World position of the camera of slot ``slot``: a square lattice centred on the origin."""
        side = int(math.ceil(math.sqrt(self.batch_frames)))
        ix, iy = slot % side, slot // side
        half = (side - 1) / 2
        return np.array([(ix - half) * self.slot_spacing_m, (iy - half) * self.slot_spacing_m, 0.0])

    def record(self) -> dict:
        """What the metadata records (everything that shapes the sample pattern)."""
        return {"mode": self.mode, "tile_px": [self.tile_width, self.tile_height],
                "tiles_per_frame": self.tiles_per_frame, "batch_frames": self.batch_frames,
                "coverage_rays_per_px": COVERAGE_SUBSAMPLES ** 2}


def projected_boxes(points_px: np.ndarray, depth_m: np.ndarray, width: int,
                    height: int) -> tuple[float, float, float, float] | None:
    """Continuous [x_min, y_min, x_max, y_max] of projected vertices, clipped to the image; None
    when nothing is in front of the camera or the box misses the image. A target straddling the
    near plane gets the whole image (its projection is unbounded)."""
    front = depth_m > NEAR_CLIP_M
    if not front.any():
        return None
    if not front.all():
        return (0.0, 0.0, float(width), float(height))
    x0, y0 = points_px.min(axis=0)
    x1, y1 = points_px.max(axis=0)
    if x1 <= 0 or y1 <= 0 or x0 >= width or y0 >= height:
        return None
    return (max(0.0, float(x0)), max(0.0, float(y0)), min(float(width), float(x1)), min(float(height), float(y1)))


def pixel_box(box: tuple[float, float, float, float], width: int, height: int,
              pad_px: int = 0) -> tuple[int, int, int, int]:
    """Integer [x0, y0, x1, y1) of the pixels a continuous box touches, padded and clipped."""
    x0 = max(0, int(math.floor(box[0])) - pad_px)
    y0 = max(0, int(math.floor(box[1])) - pad_px)
    x1 = min(width, int(math.ceil(box[2])) + pad_px)
    y1 = min(height, int(math.ceil(box[3])) + pad_px)
    return x0, y0, max(x1, x0 + 1), max(y1, y0 + 1)


def _align(n: int, limit: int) -> int:
    return min(limit, int(math.ceil(n / ROI_ALIGN_PX) * ROI_ALIGN_PX))


def plan_camera(boxes: list[list[tuple | None]], width: int, height: int, max_range_m: float,
                batch_frames: int = BATCH_FRAMES, roi: bool = True) -> CameraPlan:
    """Choose the layout from every frame's projected target boxes (``boxes[frame][target]``)."""
    n_targets = len(boxes[0]) if boxes else 0
    extent_w = extent_h = 0.0
    for frame in boxes:
        for box in frame:
            if box is not None:
                extent_w = max(extent_w, box[2] - box[0])
                extent_h = max(extent_h, box[3] - box[1])
    tile_w = _align(int(math.ceil(extent_w)) + 2 + 2 * ROI_MARGIN_PX, width)
    tile_h = _align(int(math.ceil(extent_h)) + 2 + 2 * ROI_MARGIN_PX, height)
    use_roi = (roi and n_targets > 0 and tile_w < width and tile_h < height
               and n_targets * tile_w * tile_h <= ROI_MAX_FRACTION * width * height)
    if use_roi:
        mode, tiles = "roi", n_targets
    else:
        mode, tiles, tile_w, tile_h = "full", 1, width, height
    per_launch = max(1, BATCH_PIXEL_BUDGET // (tiles * tile_w * tile_h))
    batch = max(1, min(int(batch_frames), per_launch))
    far_clip = 1.05 * max_range_m + 10.0
    return CameraPlan(mode=mode, tile_width=tile_w, tile_height=tile_h, tiles_per_frame=tiles,
                      batch_frames=batch, far_clip_m=far_clip, slot_spacing_m=2.0 * far_clip + 100.0)


def place_tile(plan: CameraPlan, box: tuple | None, width: int, height: int) -> Tile:
    """The tile of one target in one frame: centred on its box, inside the image (ROI mode), or the
    whole frame. An absent target gets a tile at the corner (rendered, never composited)."""
    if plan.mode == "full":
        return Tile(0, 0, width, height)
    if box is None:
        return Tile(0, 0, plan.tile_width, plan.tile_height)
    cx, cy = 0.5 * (box[0] + box[2]), 0.5 * (box[1] + box[3])
    x0 = int(round(cx - plan.tile_width / 2))
    y0 = int(round(cy - plan.tile_height / 2))
    x0 = min(max(0, x0), width - plan.tile_width)
    y0 = min(max(0, y0), height - plan.tile_height)
    return Tile(x0, y0, plan.tile_width, plan.tile_height)


def tile_contains(tile: Tile, box: tuple[int, int, int, int]) -> bool:
    """Whether an integer pixel box [x0, y0, x1, y1) lies inside the tile."""
    return (box[0] >= tile.x0 and box[1] >= tile.y0 and box[2] <= tile.x0 + tile.width
            and box[3] <= tile.y0 + tile.height)
