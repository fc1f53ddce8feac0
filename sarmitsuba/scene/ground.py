"""Which shapes stand for ground that continues beyond the scene (docs/physics.md (M10)).

A city model's ground, a terrain tile or a footprint city's DEM ends where its modeller stopped
drawing, not where the world ends. Its free rim is a *truncation*, and the tracer leaves out the
rim's physical-optics terms and edge currents there, as it would for a plane continuing beyond the
beam. The ``sbr`` setting ``ground_shapes`` names those shapes:

* ``auto`` (default): every shape whose id is ``ground`` or ends in ``-ground`` or ``_ground``
  (case-insensitive): the built-in scenes' and generated cities' ``ground``/``mesh-ground`` and
  Sionna RT's ``mesh-ground``;
* ``none``: no shape; every rim is an edge (a plate that really ends, a quay);
* a comma-separated list of shape ids.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..core.radar import ParameterError

__all__ = ["GROUND_SUFFIXES", "ground_shapes"]

#: ``ground_shapes = auto``: shape ids equal to ``ground`` or ending in one of these (lower case).
GROUND_SUFFIXES = ("-ground", "_ground")


def ground_shapes(setting: str, ids: Sequence[str]) -> np.ndarray:
    """bool [len(ids)]: which of the scene's shapes (their ids, in ``scene.shapes()`` order) are
    ground whose free rims are truncations.

    Raises
    ------
    ParameterError
        ``setting`` names a shape id the scene does not have (the message lists its ids).
    """
    ids = [str(i) for i in ids]
    text = setting.strip()
    if text.lower() == "auto":
        return np.array([i.lower() == "ground" or i.lower().endswith(GROUND_SUFFIXES) for i in ids], bool)
    if text.lower() in ("none", ""):
        return np.zeros(len(ids), bool)
    wanted = [w.strip() for w in text.split(",") if w.strip()]
    missing = [w for w in wanted if w not in ids]
    if missing:
        shown = ", ".join(ids[:20]) + (" ..." if len(ids) > 20 else "")
        raise ParameterError(f"sbr ground_shapes: no shape with id {', '.join(repr(m) for m in missing)} in the scene; "
                             f"give 'auto', 'none' or a comma-separated list of its shape ids ({shown})")
    return np.array([i in wanted for i in ids], bool)
