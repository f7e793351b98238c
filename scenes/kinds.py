"""The kinds of target and the nominal size of each drone kind: the one table every part of the
simulator reads (the randomised scene sampler, acoustics, RF), so a hexacopter has one size.

Sizes are overall span in metres: the size a sampled target of that kind gets (before a config's
``target_size_scale``) and the reference size at which acoustics quotes a kind's source levels.
"""
from __future__ import annotations

#: every target kind a scene may hold (the schema's ``TargetKind``; ``scenes.assets.KINDS``)
TARGET_KINDS = ("quadcopter", "hexacopter", "fixed_wing", "bird", "airliner", "helicopter")
#: the kinds that count as a drone (label "Drone", rotor/engine audio, a radio link)
DRONE_KINDS = ("quadcopter", "hexacopter", "fixed_wing")
#: nominal overall span (m) of each drone kind
DRONE_SIZE_M = {"quadcopter": 0.45, "hexacopter": 0.9, "fixed_wing": 2.0}
