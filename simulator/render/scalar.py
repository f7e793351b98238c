"""Mitsuba's scalar variant: the renderer's wavefront calls as loops over lanes (numpy in and out).

The llvm variant traces every lane of a launch in one Dr.Jit kernel; the scalar variant takes one
ray (one ``SurfaceInteraction3f``) per call. These helpers take (3, n) / (n,) numpy lanes, loop
over them with scalar Mitsuba objects and return numpy, so the renderer's data flow is the same on
both variants. Lane-parallel arithmetic (ray generation, sample jitter) stays in numpy.
"""
from __future__ import annotations

import numpy as np


def tea_float32(v0: np.ndarray, v1: np.ndarray, rounds: int = 4) -> np.ndarray:
    """Mitsuba's ``sample_tea_float32`` (Tiny Encryption Algorithm on uint32, mantissa from the top
    23 bits of the second word) for numpy uint32 arrays: the same float32 values, lane by lane."""
    v0 = np.asarray(v0, np.uint32).copy()
    v1 = np.asarray(v1, np.uint32).copy()
    total = np.uint32(0)
    with np.errstate(over="ignore"):
        for _ in range(rounds):
            total = np.uint32(total + np.uint32(0x9E3779B9))
            v0 += (((v1 << np.uint32(4)) + np.uint32(0xA341316C)) ^ (v1 + total)
                   ^ ((v1 >> np.uint32(5)) + np.uint32(0xC8013EA4)))
            v1 += (((v0 << np.uint32(4)) + np.uint32(0xAD90777D)) ^ (v0 + total)
                   ^ ((v0 >> np.uint32(5)) + np.uint32(0x7E95761E)))
    bits = (v1 >> np.uint32(9)) | np.uint32(0x3F800000)
    return bits.view(np.float32) - np.float32(1.0)


def _rows(values: list) -> np.ndarray:
    """(n, 3) float32 from a list of Color3f (read per channel: far faster than numpy's conversion)."""
    return np.array([(c[0], c[1], c[2]) for c in values], np.float32).reshape(len(values), 3)


def eval_emitter(mi, emitter, wi: np.ndarray) -> np.ndarray:
    """(n, 3) float32 radiance of ``emitter`` seen along incident directions ``wi`` (3, n)."""
    import drjit as dr

    si = dr.zeros(mi.SurfaceInteraction3f)
    evaluate, values = emitter.eval, []
    for direction in np.asarray(wi, np.float64).T.tolist():
        si.wi = direction
        values.append(evaluate(si))
    return _rows(values)


def _rays(mi, o: np.ndarray, d: np.ndarray, maxt: float):
    for (ox, oy, oz), (dx, dy, dz) in zip(np.asarray(o, np.float64).tolist(), np.asarray(d, np.float64).tolist()):
        ray = mi.Ray3f(mi.Point3f(ox, oy, oz), mi.Vector3f(dx, dy, dz))
        ray.maxt = maxt
        yield ray


def intersect(mi, scene, o: np.ndarray, d: np.ndarray, maxt: float) -> tuple[np.ndarray, np.ndarray]:
    """(primitive index int64, hit bool) of rays with origins ``o`` and unit directions ``d`` (n, 3)."""
    n = len(o)
    prim, valid = np.zeros(n, np.int64), np.zeros(n, bool)
    for i, ray in enumerate(_rays(mi, o, d, maxt)):
        si = scene.ray_intersect(ray)
        if si.is_valid():
            prim[i], valid[i] = si.prim_index, True
    return prim, valid


def emitted(mi, scene, o: np.ndarray, d: np.ndarray, maxt: float) -> np.ndarray:
    """(n, 3) float32 radiance emitted by what each ray hits first (the environment when nothing)."""
    values, zero = [], (0.0, 0.0, 0.0)
    for ray in _rays(mi, o, d, maxt):
        si = scene.ray_intersect(ray)
        emitter = si.emitter(scene)
        values.append(zero if emitter is None else emitter.eval(si))
    return _rows(values)


def path_trace(mi, scene, integrator, seed: int, o: np.ndarray, d: np.ndarray, maxt: float) -> np.ndarray:
    """(n, 3) float32 path-traced radiance per ray; one independent sampler seeded once with
    ``seed`` and advanced lane by lane (deterministic; not the llvm variant's per-lane streams)."""
    sampler = mi.load_dict({"type": "independent"})
    sampler.seed(seed)
    values = []
    for ray in _rays(mi, o, d, maxt):
        values.append(integrator.sample(scene, sampler, ray)[0])
        sampler.advance()
    return _rows(values)
