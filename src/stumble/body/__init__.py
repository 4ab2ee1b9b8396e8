"""The human models: 3D (42 DOF, SCA 2009 §4.1) and planar (seed 003 §III)."""

from stumble.body.build import Body, build

__all__ = ["Body", "build"]
