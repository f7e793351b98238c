"""The kinds of target, the nominal size of each drone kind, the size span a drawn target of each
kind gets and the steepest bank it flies a drawn turn at: the one table every part of the simulator
reads (the scene samplers, acoustics, RF, the generator's orbits), so a hexacopter has one size.

Sizes are overall span in metres. ``DRONE_SIZE_M`` is the size a sampled drone of that kind gets when
a generation config changes its kind (before the config's ``target_size_scale``) and the reference
size at which acoustics quotes a kind's source levels. ``TARGET_SIZE_RANGE_M`` is the span a target of
each kind is drawn from where a sampler draws a size (``scenes.sampling.target_size``).
"""
from __future__ import annotations

#: every target kind a scene may hold (the schema's ``TargetKind``; ``scenes.assets.KINDS``)
TARGET_KINDS = ("quadcopter", "hexacopter", "fixed_wing", "bird", "airliner", "helicopter")
#: the kinds that count as a drone (label "Drone", rotor/engine audio, a radio link)
DRONE_KINDS = ("quadcopter", "hexacopter", "fixed_wing")
#: the kinds that are not drones (a generation config's distractors, TRIDENT's confusers)
DISTRACTOR_KINDS = tuple(k for k in TARGET_KINDS if k not in DRONE_KINDS)
#: nominal overall span (m) of each drone kind
DRONE_SIZE_M = {"quadcopter": 0.45, "hexacopter": 0.9, "fixed_wing": 2.0}

#: span (m) of a drawn target's overall size, uniform. Drones: the TRIDENT scene distribution's spans
#: (d8fa57f), each around its nominal size above (small quads to F450-class 0.6 m, hexacopters to
#: 1.1 m, fixed wing 1-2.2 m). Bird, airliner and helicopter: the distractor spans of the generation
#: configs (a crow to a gull, narrow-body to wide-body wingspan, light-helicopter rotor diameter).
TARGET_SIZE_RANGE_M = {"quadcopter": (0.3, 0.6), "hexacopter": (0.6, 1.1), "fixed_wing": (1.0, 2.2),
                       "bird": (0.3, 0.8), "airliner": (30.0, 60.0), "helicopter": (8.0, 14.0)}
#: the drone rows of the table above, fitted to the Svanström benchmark's drones: the sim2real
#: synthetic-audio default (``drone_size_m``). Quadcopters span its two larger drones (DJI Phantom 4 Pro
#: 0.35 m, DJI Flame Wheel F450 0.45 m: 63 of the 74 calibration IR clips); the 0.1 m Hubsan H107D+ (11
#: clips) is left out: at the cube-law mass its sound power would be ~25 dB under an F450's
#: (docs/SIM2REAL_AUDIO.md, third pass; was 0.12-0.5 m). Hexacopters 0.5-1.1 m.
BENCHMARK_DRONE_SIZE_RANGE_M = {**{k: TARGET_SIZE_RANGE_M[k] for k in DRONE_KINDS},
                                "quadcopter": (0.3, 0.5), "hexacopter": (0.5, 1.1)}

#: steepest bank (deg) of a drawn level turn of each kind: the generator's orbit radius is at least
#: v^2 / (g tan(bank)) (``simulator.physics.trajectory.min_orbit_radius_m``), so the coordinated-turn
#: bank arctan(v^2 / (g r)) the renderer poses stays physical. Helicopter and airliner 30: instrument
#: and airline turns are standard-rate (3 deg/s) turns capped at 25-30 deg of bank (a standard-rate
#: turn at 20-60 m/s is a 6-18 deg bank). Multirotors 35 (tilt of the thrust vector): between the
#: autopilots' default lean limits, ArduCopter ANGLE_MAX 30 deg and PX4 MPC_TILTMAX_AIR 45 deg.
#: Fixed wing 45: ArduPlane's default roll limit. Bird 60: birds turn steeply; 60 is the renderer's
#: bank clip (``simulator.physics.timeline``), so a bird's drawn orbit is never clipped there.
MAX_BANK_DEG = {"quadcopter": 35.0, "hexacopter": 35.0, "fixed_wing": 45.0, "bird": 60.0,
                "airliner": 30.0, "helicopter": 30.0}
