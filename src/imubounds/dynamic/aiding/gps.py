"""GPS position error bounds (METHOD.md 2.2).

CEP (m, 50 % circle) -> DRMS = CEP/sqrt(ln 2) -> per fix DRMS(i) = HDOP(i)·DRMS(HDOP=1).
Two box half-widths are offered:

* ``mean`` (the paper): the mean radial error mu_e = (sqrt(pi)/2)·DRMS(i);
  with CEP 3 m and HDOP 1 this is 3.19 m. Under the same Rayleigh model such a
  box holds the true position only about 54 % of the time.
* ``p=P`` (default ``p=0.999``): the radius D_p = DRMS(i)·sqrt(-ln(1-P)) that
  contains the true position with probability P.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from imubounds.errors import OptionError
from imubounds.io.drive import DEFAULT_CEP_M, DEFAULT_HDOP  # the GNSS defaults, defined once

#: Default probability level of the position box.
DEFAULT_BOX = "p=0.999"


def cep_to_drms(cep_m: float) -> float:
    """DRMS in m from CEP in m under the Rayleigh model: ``CEP/sqrt(ln 2)`` (= 1.201·CEP)."""
    if not (math.isfinite(cep_m) and cep_m > 0):
        raise OptionError(f"--gps-cep must be a positive number of metres, got {cep_m!r}")
    return cep_m / math.sqrt(math.log(2.0))


def mean_error(drms_m: float | np.ndarray) -> float | np.ndarray:
    """Mean radial error in m, ``(sqrt(pi)/2)·DRMS`` (the paper's mu_e)."""
    return 0.5 * math.sqrt(math.pi) * drms_m


def radius_at_probability(drms_m: float | np.ndarray, p: float) -> float | np.ndarray:
    """Radius in m holding the true position with probability ``p``: ``DRMS·sqrt(-ln(1-p))``."""
    if not (0.0 < p < 1.0):
        raise OptionError(f"GPS box probability must lie in (0, 1), got {p!r}")
    return drms_m * math.sqrt(-math.log1p(-p))


@dataclass(frozen=True)
class GpsBoxSpec:
    """How GPS boxes are built: ``kind`` is ``"mean"`` or ``"p"``; ``p`` the level."""

    kind: str
    p: float | None = None

    def factor(self) -> float:
        """Half-width of the box divided by DRMS(i) (dimensionless)."""
        if self.kind == "mean":
            return 0.5 * math.sqrt(math.pi)
        assert self.p is not None
        return math.sqrt(-math.log1p(-self.p))

    def label(self) -> str:
        return "mean" if self.kind == "mean" else f"p={self.p:g}"

    def containment(self) -> float:
        """Probability that the box's circle holds the true position (Rayleigh model)."""
        f = self.factor()
        return 1.0 - math.exp(-f * f)


def parse_gps_box(text: str) -> GpsBoxSpec:
    """Parse ``--gps-box``: ``mean`` or ``p=0.999``."""
    s = text.strip().lower()
    if s == "mean":
        return GpsBoxSpec("mean")
    if s.startswith("p="):
        try:
            p = float(s[2:])
        except ValueError:
            p = float("nan")
        if 0.0 < p < 1.0:
            return GpsBoxSpec("p", p)
    raise OptionError(f"--gps-box must be 'mean' or 'p=P' with 0<P<1 (e.g. p=0.999), got {text!r}")


def gps_box_halfwidths(
    hdop: np.ndarray,
    cep_m: float = DEFAULT_CEP_M,
    box: GpsBoxSpec | str = DEFAULT_BOX,
    default_hdop: float = DEFAULT_HDOP,
) -> tuple[np.ndarray, int]:
    """Half-width in m of each fix's square position box ``[x ± h] × [y ± h]``.

    Parameters
    ----------
    hdop:
        HDOP per fix (dimensionless); NaN or non-positive means "not reported"
        and is replaced by ``default_hdop``.
    cep_m:
        Receiver CEP in m at HDOP 1.
    box:
        ``"mean"`` (paper) or ``"p=P"``.

    Returns
    -------
    (halfwidths, n_defaulted):
        Half-widths in m, and how many fixes used the default HDOP.
    """
    spec = parse_gps_box(box) if isinstance(box, str) else box
    if not (math.isfinite(default_hdop) and default_hdop > 0):
        raise OptionError(f"default HDOP must be positive, got {default_hdop!r}")
    h = np.asarray(hdop, dtype=float).copy()
    missing = ~np.isfinite(h) | (h <= 0)
    h[missing] = default_hdop
    return h * cep_to_drms(cep_m) * spec.factor(), int(missing.sum())
