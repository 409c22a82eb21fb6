"""noise: not a deterministic effect; its sigmas are the simulator's scatter and reading noise."""

from __future__ import annotations

import numpy as np

from campaign.effects.base import Effect


def non_negative(name: str, p: dict[str, float]) -> str | None:
    return "'effects.noise' sigmas must be >= 0" if any(v < 0 for v in p.values()) else None


EFFECT = Effect(
    "noise", 200, {"sigma_um": "per-approach positioning scatter, µm",
                   "reading_sigma_um": "per-sample instrument noise, µm"},
    lambda p, x, d, t, w: np.zeros(np.broadcast(x, d, t, w).shape),
    defaults={"reading_sigma_um": 0.0}, check=non_negative)
