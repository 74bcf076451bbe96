"""How each unit of a fleet is analysed: :class:`FleetSettings` (the ``imubounds static``
settings that matter), the five IEEE 952 terms a fleet reports, the progress callback."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field
from typing import Any

from imubounds.errors import OptionError
from imubounds.stationary.allan_grammar import DEFAULT_TAU_POINTS

__all__ = ["TERMS", "FleetSettings", "Progress"]

TERMS: tuple[str, ...] = ("Q", "N", "B", "K", "R")
#: ``progress(stage, done, total)``: ``"hash"`` then ``"units"`` (interleaved on Dask).
Progress = Callable[[str, int, int], None]


@dataclass(frozen=True)
class FleetSettings:
    """How each unit is analysed (the ``imubounds static`` settings that matter).

    ``read`` holds the keyword arguments of :func:`imubounds.io.read_imu`
    (``rate_hz``, ``columns``, ``gyro_unit``, ...); ``memory_limit`` routes a
    log larger than it through the out-of-core path, as ``imubounds static``.
    """

    taus: str | int | tuple[float, ...] = DEFAULT_TAU_POINTS
    estimator: str = "overlapping"
    confidence: float = 0.683
    terms_from: str = "fit"
    memory_limit: str | int = "1GiB"
    read: Mapping[str, Any] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        """The settings as JSON (also the cache key's part): read options at their default
        (``on_gap="refuse"``) are left out, so that the command line and Python share it."""
        from dataclasses import fields

        from imubounds.io.assemble import ReadOptions

        defaults = {f.name: f.default for f in fields(ReadOptions)}
        d = asdict(self)
        d["read"] = {k: v for k, v in dict(self.read).items()
                     if v is not None and not (k in defaults and v == defaults[k])}  # fmt: skip
        if isinstance(self.taus, tuple):
            d["taus"] = list(self.taus)
        return d

    def check(self) -> None:
        """Refuse, before any unit is read, settings every unit would fail on.

        Raises
        ------
        OptionError
            A confidence outside (0, 1), an unknown estimator or ``terms_from``, an
            unreadable memory setting.
        """
        from imubounds.stationary.allan import ESTIMATORS
        from imubounds.stationary.stream import parse_memory

        c = self.confidence
        if isinstance(c, bool) or not isinstance(c, (int, float)) or not 0 < c < 1:
            raise OptionError(f"confidence must be between 0 and 1 (exclusive), got {c!r}")
        if self.estimator not in ESTIMATORS:
            raise OptionError(
                f"unknown estimator {self.estimator!r}; use one of {', '.join(ESTIMATORS)}"
            )
        if self.terms_from not in ("fit", "slope"):
            raise OptionError(f"terms_from must be 'fit' or 'slope', got {self.terms_from!r}")
        parse_memory(self.memory_limit, "memory_limit")

    def static_settings(self) -> Any:
        """The :class:`~imubounds.stationary.pipeline.StaticSettings` of a unit (no models)."""
        from imubounds.stationary.pipeline import StaticSettings

        return StaticSettings(
            taus=self.taus,
            estimator=self.estimator,
            confidence=self.confidence,
            terms_from=self.terms_from,  # type: ignore[arg-type]
            models=(),
        )
