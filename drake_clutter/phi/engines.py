"""phi's engines behind one factory: `build_phi` returns the phi of a spec in the engine its
configuration names (``dynamics.engine``): `dynamics.Phi` in Drake or `mujoco_phi.MujocoPhi` in
MuJoCo. Both engines' modules are imported from here and neither imports this one, so the
engine choice adds no import cycle.
"""

from __future__ import annotations

from drake_clutter.phi.dynamics import Phi, PhiBase, PhiSpec


def build_phi(spec: PhiSpec) -> PhiBase:
    """The phi of ``spec`` in its engine (``spec.config.engine``): `Phi` in Drake, or
    `mujoco_phi.MujocoPhi` (MuJoCo imported on first use)."""
    if spec.config.engine == "mujoco":
        from drake_clutter.phi.mujoco_phi import MujocoPhi

        return MujocoPhi(spec)
    return Phi(spec)
