"""Contact sheets of the camera model: the ideal sensor (left) and the default camera model (right)
for the same scene and seed. Writes docs/images/sensor_<scene>.png.

    PYTHONPATH=. .venv/bin/python docs/make_sensor_figures.py [scene ...]
"""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np

from scenes import load_scenario
from simulator.dataset.preview import contact_sheet
from simulator.dataset.sequence import render_sequence
from simulator.formats.native import write_png

OUT = Path(__file__).with_name("images")
SCENES = {"dusk_crossover": 1.0, "clear_day_quad": 1.0}   # scene -> seconds rendered


def sheet_for(scene: str, seconds: float, sensor: str, work: Path) -> np.ndarray:
    s = load_scenario(scene)
    s = s.model_copy(update={"duration_s": seconds,
                             "camera_rig": s.camera_rig.model_copy(update={"sensor": sensor})})
    out = render_sequence(s, 0, work / sensor, progress=False)
    path = contact_sheet(out["native"], work / f"{sensor}.png", tile_width=400)
    return cv2.cvtColor(cv2.imread(str(path)), cv2.COLOR_BGR2RGB)


def main(scenes: list[str]) -> None:
    for scene in scenes:
        with tempfile.TemporaryDirectory() as tmp:
            sheets = [sheet_for(scene, SCENES.get(scene, 1.0), sensor, Path(tmp)) for sensor in ("ideal", "camera")]
        height = max(s.shape[0] for s in sheets)
        bars = []
        for label, s in zip(("sensor: ideal (rendered radiance, no camera)", "sensor: camera (default camera model)"),
                            sheets):
            bar = np.full((26, s.shape[1], 3), 60, np.uint8)
            cv2.putText(bar, label, (8, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (255, 255, 0), 1, cv2.LINE_AA)
            pad = np.zeros((height - s.shape[0], s.shape[1], 3), np.uint8)
            bars.append(np.vstack([bar, s, pad]))
        gap = np.full((bars[0].shape[0], 8, 3), 255, np.uint8)
        write_png(OUT / f"sensor_{scene}.png", np.hstack([bars[0], gap, bars[1]]))
        print("wrote", OUT / f"sensor_{scene}.png")


if __name__ == "__main__":
    main(sys.argv[1:] or list(SCENES))
