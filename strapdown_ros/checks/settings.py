"""The settings a bag's streams are verified with: the ones they were generated with.

``strapdown-sim generate`` and ``bag_recorder`` store the scenario's ``gravity_model`` in the
bag's ``custom_data`` (``strapdown_ros.plan.metadata.bag_custom_data``). The exactness rule
(docs/interface.md §3) holds for the model the increments were computed with, so a spherical
bag checked against J2 fails by the models' difference (~9e-5 m/s per 5 ms cycle at 45°
latitude); ``check`` and ``report`` therefore take the model from the metadata, and an explicit
choice (``--gravity-model``) overrides it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

__all__ = ["DEFAULT_GRAVITY_MODEL", "GRAVITY_MODELS", "CheckSettings", "check_settings"]

#: The gravitation models of docs/interface.md §1 (``strapdown_ros.core.gravity``).
GRAVITY_MODELS = ("j2", "spherical")
#: The scenario's default, used for a bag whose metadata names no model.
DEFAULT_GRAVITY_MODEL = "j2"


class SettingsError(ValueError):
    """The bag's metadata names a setting this version cannot verify."""


@dataclass(frozen=True)
class CheckSettings:
    """How a bag's streams are verified.

    ``gravity_model``: ``j2`` or ``spherical``; ``source``: where it comes from (``metadata``,
    ``override`` or ``default``); ``generator``: the bag's ``custom_data['generator']``
    (``strapdown_ros`` for bags this package wrote, empty when absent).
    """

    gravity_model: str
    source: str
    generator: str = ""
    recorded_model: str | None = None  #: the model the metadata names (None: it names none)

    @property
    def from_strapdown(self) -> bool:
        """Whether the bag's metadata says strapdown_ros wrote it."""
        return self.generator == "strapdown_ros"

    def describe(self) -> str:
        """One line: the model and where it comes from."""
        if self.source == "metadata":
            return f"gravity model {self.gravity_model} (from the bag's metadata)"
        if self.source == "override":
            recorded = (
                f"; the bag's metadata says {self.recorded_model}"
                if self.recorded_model and self.recorded_model != self.gravity_model
                else ""
            )
            return f"gravity model {self.gravity_model} (chosen with --gravity-model{recorded})"
        return (
            f"gravity model {self.gravity_model} (default: the bag's metadata names none; "
            "--gravity-model to choose)"
        )


def check_settings(
    custom_data: Mapping[str, str], gravity_model: str | None = None
) -> CheckSettings:
    """The settings to verify a bag with: ``gravity_model`` if given, else the metadata's.

    Raises :class:`SettingsError` when the model (given or recorded) is not one of
    :data:`GRAVITY_MODELS`.
    """
    recorded = custom_data.get("gravity_model")
    recorded = recorded.strip() if isinstance(recorded, str) and recorded.strip() else None
    generator = str(custom_data.get("generator", "")).strip()
    if gravity_model is not None:
        model, source = gravity_model, "override"
    elif recorded is not None:
        model, source = recorded, "metadata"
    else:
        model, source = DEFAULT_GRAVITY_MODEL, "default"
    if model not in GRAVITY_MODELS:
        where = "--gravity-model" if source == "override" else "the bag's metadata"
        raise SettingsError(
            f"gravity model {model!r} from {where} is not one of {', '.join(GRAVITY_MODELS)}"
        )
    return CheckSettings(model, source, generator, recorded)
