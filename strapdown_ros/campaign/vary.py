"""``--vary KEY=SPEC``: scenario values drawn per campaign run.

``SPEC`` is ``normal(MEAN, SIGMA)`` or ``uniform(LOW, HIGH)``; the arguments are numbers, or
lists of numbers for a vector key (drawn per element), written as YAML flow values, e.g.::

    --vary navigator.initial_errors.attitude_rph_deg='normal([0, 0, 0], [0.01, 0.01, 0.1])'
    --vary imu_errors.0.gyro_bias_dph='uniform(-1, 1)'

``KEY`` is a dotted scenario key as for ``--set``. A draw is a plain override: the run's
scenario is validated by the scenario model like any other, so a key that does not exist or a
drawn value out of range is reported with its key (docs/campaigns.md).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

import numpy as np
import yaml

from strapdown_ros.config import ScenarioError

__all__ = ["DISTRIBUTIONS", "Vary", "parse_vary"]

DISTRIBUTIONS = ("normal", "uniform")
_SPEC = re.compile(r"^\s*(?P<dist>[a-z]+)\s*\((?P<args>.*)\)\s*$", re.S)


@dataclass(frozen=True)
class Vary:
    """One varied key: ``key`` drawn from ``distribution`` with parameters ``a``, ``b``.

    ``normal``: a = mean, b = standard deviation (>= 0); ``uniform``: a = low, b = high
    (low <= high). ``a`` and ``b`` are arrays of the same shape: () for a number, (n,) for a
    vector key.
    """

    key: str
    distribution: str
    a: np.ndarray
    b: np.ndarray
    text: str

    def draw(self, rng: np.random.Generator) -> float | list[float]:
        """One value (a number or a list) from ``rng``."""
        if self.distribution == "normal":
            value = rng.normal(self.a, self.b)
        else:
            value = rng.uniform(self.a, self.b)
        value = np.asarray(value, dtype=np.float64)
        return float(value) if value.ndim == 0 else [float(v) for v in value]

    def override(self, value: float | list[float]) -> str:
        """The ``--set`` override of a drawn value (exact: repr of float64)."""
        if isinstance(value, list):
            return f"{self.key}=[{', '.join(repr(v) for v in value)}]"
        return f"{self.key}={value!r}"

    def center(self) -> float | list[float]:
        """A representative value (mean, or mid-range) used to validate the key up front."""
        c = self.a if self.distribution == "normal" else (self.a + self.b) / 2
        return float(c) if c.ndim == 0 else [float(v) for v in c]


def _numbers(value: Any, where: str) -> np.ndarray:
    arr = np.asarray(value, dtype=object)
    if arr.ndim > 1:
        raise ScenarioError(where, f"must be a number or a list of numbers, got {value!r}")
    flat = arr.reshape(-1)
    for item in flat:
        if isinstance(item, bool) or not isinstance(item, int | float) or not np.isfinite(item):
            raise ScenarioError(where, f"must be a finite number or a list of them, got {value!r}")
    return np.asarray(value, dtype=np.float64)


def parse_vary(text: str) -> Vary:
    """Parse ``KEY=normal(MEAN, SIGMA)`` / ``KEY=uniform(LOW, HIGH)``.

    Raises
    ------
    ScenarioError
        ``--vary <text>: <problem>`` for a malformed specification.
    """
    where = f"--vary {text}"
    if "=" not in text:
        raise ScenarioError(where, "must look like dotted.key=normal(mean, sigma)")
    key, spec = (part.strip() for part in text.split("=", 1))
    if not key or any(not part for part in key.split(".")):
        raise ScenarioError(where, "the key must be a dotted scenario key")
    match = _SPEC.match(spec)
    if not match or match["dist"] not in DISTRIBUTIONS:
        raise ScenarioError(
            where, f"the value must be one of {', '.join(d + '(a, b)' for d in DISTRIBUTIONS)}"
        )
    try:
        args = yaml.safe_load(f"[{match['args']}]")
    except yaml.YAMLError:
        args = None
    if not isinstance(args, list) or len(args) != 2:
        raise ScenarioError(where, f"{match['dist']} takes two arguments, got {match['args']!r}")
    a, b = _numbers(args[0], where), _numbers(args[1], where)
    if a.shape != b.shape:
        raise ScenarioError(where, "both arguments must have the same length")
    if match["dist"] == "normal" and np.any(b < 0):
        raise ScenarioError(where, "the standard deviation must be >= 0")
    if match["dist"] == "uniform" and np.any(b < a):
        raise ScenarioError(where, "uniform(low, high) needs low <= high")
    return Vary(key, match["dist"], a, b, text)
