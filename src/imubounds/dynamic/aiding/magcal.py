"""Hard- and soft-iron calibration of a raw magnetometer by an ellipse (or ellipsoid) fit.

No reference heading is needed (no GNSS, no swing): the field the sensor sees
while the vehicle turns traces an ellipse in the level plane,

    m_h = W^-1 H (cos psi, sin psi) + c + e,

with hard iron ``c`` (an offset), soft iron ``W^-1`` (a symmetric distortion),
the horizontal field ``H`` and a disturbance ``e``. Fitting the ellipse gives
``c`` and ``W`` up to scale; the corrected vector ``W (m_h - c) / H`` lies on
the unit circle and its angle is the magnetic heading (clockwise from north;
in the FLU body frame the field's forward component is ``cos psi`` and its
left component ``sin psi``).

Tilt: with an attitude stream the raw vectors are levelled (roll, pitch)
before the fit, so the fit sees the horizontal field; without one the vehicle
is assumed level and the effect of its tilt ends up in the residual. When the
data span three dimensions (a vehicle that rolls and pitches a lot) and an
attitude stream exists, the fit is an ellipsoid in the body frame and the
corrected vectors are levelled afterwards (``mode="3d"``).

What the residual says, and what it cannot: the radial residual ``|W (m -
c)/H| - 1`` of each sample measures the disturbance of the field seen during
this drive; under the stated assumption that the disturbance is isotropic,
the heading error it causes (the tangential part) has the same size. A
constant rotation (the magnetometer's yaw misalignment to the vehicle axis,
a rotational part of the soft iron) leaves the ellipse unchanged and is
invisible to any self-calibration: it is a separate, stated allowance
(``heading.alignment_deg``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from imubounds.errors import AnalysisError, OptionError
from imubounds.frames import level_vectors

#: Heading coverage (deg) below which an ellipse fit is refused: a short arc does not
#: determine the ellipse.
MIN_COVERAGE_DEG = 270.0
#: Minimum number of samples for a fit.
MIN_SAMPLES = 20


@dataclass(frozen=True)
class MagCalibration:
    """A fitted hard/soft-iron calibration.

    Attributes
    ----------
    mode:
        ``"2d"`` (ellipse in the level plane) or ``"3d"`` (ellipsoid in the body).
    hard_iron:
        Offset in the data's unit: (2,) in the level plane, or (3,) in the body.
    soft_iron:
        Symmetric matrix (2x2 or 3x3) taking ``m - hard_iron`` onto the unit
        circle (sphere): the correction, field strength included.
    field:
        Horizontal field strength, in the data's unit.
    levelled:
        True if the samples were tilt-compensated with an attitude stream.
    n:
        Samples used.
    coverage_deg:
        Heading range the samples cover (10 deg bins), deg.
    residual_rms, residual_max:
        RMS and max of the radial residual ``|corrected| - 1`` (fraction of the field).
    """

    mode: str
    hard_iron: np.ndarray
    soft_iron: np.ndarray
    field: float
    levelled: bool
    n: int
    coverage_deg: float
    residual_rms: float
    residual_max: float
    notes: list[str] = field(default_factory=list)

    def corrected(
        self, mag: np.ndarray, roll: np.ndarray | None = None, pitch: np.ndarray | None = None
    ) -> np.ndarray:
        """Corrected horizontal field (n, 2) in the level frame (x forward, y left), unit
        length for an undisturbed sample."""
        m = np.asarray(mag, dtype=float)
        if self.levelled and (roll is None or pitch is None):
            raise OptionError("this calibration was fitted on levelled data: give roll, pitch")
        if self.mode == "3d":
            c = level_vectors((m - self.hard_iron) @ self.soft_iron.T, roll, pitch)  # type: ignore[arg-type]
            return c[:, :2]
        if self.levelled:
            m = level_vectors(m, roll, pitch)  # type: ignore[arg-type]
        return (m[:, :2] - self.hard_iron) @ self.soft_iron.T

    def heading(
        self, mag: np.ndarray, roll: np.ndarray | None = None, pitch: np.ndarray | None = None
    ) -> np.ndarray:
        """Magnetic heading (rad, clockwise from magnetic north, [0, 2 pi)) of raw samples."""
        c = self.corrected(mag, roll, pitch)
        return np.mod(np.arctan2(c[:, 1], c[:, 0]), 2 * math.pi)

    def residual(
        self, mag: np.ndarray, roll: np.ndarray | None = None, pitch: np.ndarray | None = None
    ) -> np.ndarray:
        """Radial residual ``|corrected| - 1`` (2d) of raw samples."""
        c = self.corrected(mag, roll, pitch)
        return np.hypot(c[:, 0], c[:, 1]) - 1.0

    def to_dict(self) -> dict[str, Any]:
        return {
            "mode": self.mode,
            "hard_iron": self.hard_iron.tolist(),
            "soft_iron": self.soft_iron.tolist(),
            "field": self.field,
            "levelled": self.levelled,
            "n": self.n,
            "coverage_deg": self.coverage_deg,
            "residual_rms": self.residual_rms,
            "residual_max": self.residual_max,
            "notes": list(self.notes),
        }


def _sym_sqrt(m: np.ndarray) -> np.ndarray:
    w, v = np.linalg.eigh(0.5 * (m + m.T))
    if np.any(w <= 0):
        raise AnalysisError("the magnetometer samples do not lie on an ellipse (fit not definite)")
    return (v * np.sqrt(w)) @ v.T


def fit_ellipse(xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Ellipse through 2-D points: (centre (2,), S (2x2 symmetric)) with |S (p - centre)| = 1.

    An algebraic conic fit (on normalised data) refined by geometric least squares
    on the radial residual.
    """
    from scipy.optimize import least_squares

    p = np.asarray(xy, dtype=float)
    mu = p.mean(axis=0)
    scale = float(np.sqrt(np.mean(np.sum((p - mu) ** 2, axis=1)))) or 1.0
    q = (p - mu) / scale
    x, y = q[:, 0], q[:, 1]
    d = np.column_stack([x * x, x * y, y * y, x, y, np.ones_like(x)])
    a, b, c, dd, e, f = np.linalg.svd(d, full_matrices=False)[2][-1]
    m = np.array([[a, b / 2], [b / 2, c]])
    if np.trace(m) < 0:
        m, dd, e, f = -m, -dd, -e, -f
    if np.linalg.det(m) <= 0:
        raise AnalysisError(
            "the horizontal magnetometer samples do not trace an ellipse (the vehicle must "
            "turn through most of a full circle)"
        )
    ctr = np.linalg.solve(2 * m, -np.array([dd, e]))
    k = ctr @ m @ ctr - f
    if k <= 0:
        raise AnalysisError("the magnetometer ellipse fit is degenerate")
    s0 = _sym_sqrt(m / k)

    def resid(v: np.ndarray) -> np.ndarray:
        s = np.array([[v[2], v[3]], [v[3], v[4]]])
        r = (q - v[:2]) @ s.T
        return np.hypot(r[:, 0], r[:, 1]) - 1.0

    v0 = np.array([ctr[0], ctr[1], s0[0, 0], s0[0, 1], s0[1, 1]])
    v = least_squares(resid, v0, method="lm").x
    s = np.array([[v[2], v[3]], [v[3], v[4]]])
    if np.linalg.det(s) <= 0 or np.trace(s) <= 0:
        s, v = s0, v0
    return mu + scale * v[:2], s / scale


def fit_ellipsoid(xyz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Ellipsoid through 3-D points: (centre (3,), S (3x3 symmetric)) with |S (p - c)| = 1."""
    from scipy.optimize import least_squares

    p = np.asarray(xyz, dtype=float)
    mu = p.mean(axis=0)
    scale = float(np.sqrt(np.mean(np.sum((p - mu) ** 2, axis=1)))) or 1.0
    q = (p - mu) / scale
    x, y, z = q.T
    d = np.column_stack(
        [x * x, y * y, z * z, 2 * x * y, 2 * x * z, 2 * y * z, 2 * x, 2 * y, 2 * z,
         np.ones_like(x)]
    )
    v = np.linalg.svd(d, full_matrices=False)[2][-1]
    m = np.array([[v[0], v[3], v[4]], [v[3], v[1], v[5]], [v[4], v[5], v[2]]])
    g, f = v[6:9], v[9]
    if np.trace(m) < 0:
        m, g, f = -m, -g, -f
    if np.any(np.linalg.eigvalsh(m) <= 0):
        raise AnalysisError("the magnetometer samples do not lie on an ellipsoid")
    ctr = np.linalg.solve(m, -g)
    k = ctr @ m @ ctr - f
    if k <= 0:
        raise AnalysisError("the magnetometer ellipsoid fit is degenerate")
    s0 = _sym_sqrt(m / k)
    iu = np.triu_indices(3)

    def unpack(w: np.ndarray) -> np.ndarray:
        s = np.zeros((3, 3))
        s[iu] = w[3:]
        return s + np.triu(s, 1).T

    def resid(w: np.ndarray) -> np.ndarray:
        r = (q - w[:3]) @ unpack(w).T
        return np.linalg.norm(r, axis=1) - 1.0

    w0 = np.concatenate([ctr, s0[iu]])
    w = least_squares(resid, w0, method="lm").x
    s = unpack(w)
    if np.any(np.linalg.eigvalsh(s) <= 0):
        s, w = s0, w0
    return mu + scale * w[:3], s / scale


def heading_coverage_deg(heading_rad: np.ndarray, bin_deg: float = 10.0) -> float:
    """How much of the circle the headings cover, in degrees (bins of ``bin_deg`` hit)."""
    h = np.mod(np.degrees(np.asarray(heading_rad, dtype=float)), 360.0)
    bins = np.unique(np.floor(h / bin_deg).astype(int))
    return float(bins.size * bin_deg)


def fit_magnetometer(
    mag: np.ndarray,
    roll: np.ndarray | None = None,
    pitch: np.ndarray | None = None,
    *,
    mode: str = "auto",
    min_coverage_deg: float = MIN_COVERAGE_DEG,
) -> MagCalibration:
    """Fit the hard and soft iron of raw magnetometer samples (n, 3) in body FLU axes.

    Parameters
    ----------
    mag:
        Raw samples, any unit (the field strength is fitted).
    roll, pitch:
        Attitude (rad) at the samples, for tilt compensation; None: level.
    mode:
        ``"2d"``, ``"3d"`` (needs ``roll``/``pitch`` and samples spanning three
        dimensions) or ``"auto"`` (3d when the samples span three dimensions and
        the attitude is known, else 2d).
    min_coverage_deg:
        Refuse (:class:`AnalysisError`) when the corrected headings cover less
        of the circle: the ellipse is then not determined.
    """
    m = np.asarray(mag, dtype=float)
    if m.ndim != 2 or m.shape[1] != 3:
        raise OptionError("magnetometer samples must be an (n, 3) array")
    ok = np.isfinite(m).all(axis=1)
    levelled = roll is not None and pitch is not None
    if levelled:
        r_ = np.asarray(roll, dtype=float)
        p_ = np.asarray(pitch, dtype=float)
        ok &= np.isfinite(r_) & np.isfinite(p_)
        r_, p_ = r_[ok], p_[ok]
    m = m[ok]
    if m.shape[0] < MIN_SAMPLES:
        raise AnalysisError(
            f"the magnetometer calibration needs at least {MIN_SAMPLES} samples, got {m.shape[0]}"
        )
    if mode not in ("auto", "2d", "3d"):
        raise OptionError(f"magnetometer fit mode must be auto, 2d or 3d, got {mode!r}")
    spread = np.linalg.svd(m - m.mean(axis=0), compute_uv=False)
    three_d = bool(spread[2] > 0.3 * spread[0])
    if mode == "3d" and not levelled:
        raise OptionError("a 3-D magnetometer fit needs the attitude (roll, pitch)")
    use_3d = mode == "3d" or (mode == "auto" and three_d and levelled)
    notes: list[str] = []
    if use_3d:
        ctr, s = fit_ellipsoid(m)
        c3 = level_vectors((m - ctr) @ s.T, r_, p_)
        h_frac = float(np.median(np.hypot(c3[:, 0], c3[:, 1])))  # cos(inclination)
        c = c3[:, :2] / h_frac
        total = 1.0 / float(np.mean(np.linalg.eigvalsh(s)))
        cal_args: tuple[Any, ...] = ("3d", ctr, s / h_frac, total * h_frac)
    else:
        pts = level_vectors(m, r_, p_) if levelled else m
        ctr, s = fit_ellipse(pts[:, :2])
        c = (pts[:, :2] - ctr) @ s.T
        field_strength = 1.0 / float(np.sqrt(np.linalg.det(s)))
        cal_args = ("2d", ctr, s, field_strength)
        if not levelled:
            notes.append("no attitude: the vehicle is taken as level; its tilt during the drive "
                         "is part of the residual")
    radial = np.hypot(c[:, 0], c[:, 1]) - 1.0
    heading = np.arctan2(c[:, 1], c[:, 0])
    cover = heading_coverage_deg(heading)
    if cover < min_coverage_deg:
        raise AnalysisError(
            f"the drive turns through {cover:.0f} deg of heading only; an ellipse fit of the "
            f"magnetometer needs {min_coverage_deg:.0f} deg or more (drive a full circle, give a "
            "swing calibration file, heading.deviation_deg, or fit to the GNSS course explicitly)"
        )
    return MagCalibration(
        mode=cal_args[0],
        hard_iron=np.asarray(cal_args[1], dtype=float),
        soft_iron=np.asarray(cal_args[2], dtype=float),
        field=float(cal_args[3]),
        levelled=levelled,
        n=int(m.shape[0]),
        coverage_deg=cover,
        residual_rms=float(np.sqrt(np.mean(radial**2))),
        residual_max=float(np.max(np.abs(radial))),
        notes=notes,
    )
