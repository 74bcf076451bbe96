"""Hard- and soft-iron calibration of a raw magnetometer by an ellipse fit (no reference).

No reference heading is needed (no GNSS, no swing). The sensor reads

    m = W^-1 C_bn^T F + h + e,

with the Earth's field ``F`` (horizontal ``H`` towards magnetic north,
vertical ``V``), the body attitude ``C_bn`` (roll, pitch, heading), hard iron
``h`` (an offset), soft iron ``W^-1`` (a symmetric distortion) and a
disturbance ``e``. The corrected vector ``c = W (m - h)``, levelled with the
attitude's roll and pitch, is the field in the level frame of the vehicle:
its horizontal part traces a circle of radius ``H`` as the vehicle turns and
its vertical part stays ``V``. The fit finds ``h`` (3), the symmetric ``W``
(6, scaled so that the circle has radius 1) and ``V/H`` by least squares on
both (initialised by an algebraic ellipse fit of the levelled samples); the
corrected horizontal angle is the magnetic heading (clockwise from north: in
the FLU body frame the field's forward part is ``cos psi`` and its left part
``sin psi``). The vertical hard iron is observable only through tilt changes;
when the vehicle stays level it does not matter either.

Without an attitude stream the vehicle is taken as level; its tilt changes
then end up in the residual.

What the residual says, and what it cannot: the radial residual ``|c_h| - 1``
of each sample measures the disturbance of the field seen during this drive.
Its robust standard deviation (MAD) is the noise level; under the stated
assumption that the disturbance is isotropic, the heading error it causes
(the tangential part) has the same distribution. Samples whose radial
residual exceeds ``k`` noise levels show a disturbed field and are dropped
(counted). A constant rotation (the magnetometer's yaw misalignment to the
vehicle axis, a rotational part of the soft iron) leaves the fit unchanged
and is invisible to any self-calibration: it is a separate, stated allowance
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
    hard_iron:
        Offset (3,) in the data's unit, body axes.
    soft_iron:
        Symmetric 3x3 matrix taking ``m - hard_iron`` to the corrected field in
        units of the horizontal field ``field``.
    vertical_ratio:
        Vertical over horizontal field (``V/H``; negative north of the magnetic
        equator, body z up).
    horizontal_field:
        Horizontal field strength, in the data's unit.
    levelled:
        True if the samples were tilt-compensated with an attitude stream.
    n:
        Samples used.
    coverage_deg:
        Heading range the samples cover (10 deg bins), deg.
    residual_sigma:
        Robust standard deviation (1.4826 MAD) of the radial residual, as a
        fraction of the horizontal field.
    residual_rms, residual_max:
        RMS and largest radial residual of the samples used.
    """

    hard_iron: np.ndarray
    soft_iron: np.ndarray
    vertical_ratio: float
    horizontal_field: float
    levelled: bool
    n: int
    coverage_deg: float
    residual_sigma: float
    residual_rms: float
    residual_max: float
    notes: list[str] = field(default_factory=list)

    def corrected(
        self, mag: np.ndarray, roll: np.ndarray | None = None, pitch: np.ndarray | None = None
    ) -> np.ndarray:
        """Corrected field (n, 3) in the level frame (x forward, y left, z up), in units of
        the horizontal field: the horizontal part has length 1 for an undisturbed sample."""
        if self.levelled and (roll is None or pitch is None):
            raise OptionError("this calibration was fitted on levelled data: give roll, pitch")
        c = (np.asarray(mag, dtype=float) - self.hard_iron) @ self.soft_iron.T
        if roll is None or pitch is None:
            return c
        return level_vectors(c, roll, pitch)

    def heading(
        self, mag: np.ndarray, roll: np.ndarray | None = None, pitch: np.ndarray | None = None
    ) -> np.ndarray:
        """Magnetic heading (rad, clockwise from magnetic north, [0, 2 pi)) of raw samples."""
        c = self.corrected(mag, roll, pitch)
        return np.mod(np.arctan2(c[:, 1], c[:, 0]), 2 * math.pi)

    def residual(
        self, mag: np.ndarray, roll: np.ndarray | None = None, pitch: np.ndarray | None = None
    ) -> np.ndarray:
        """Radial residual ``|corrected horizontal| - 1`` of raw samples."""
        c = self.corrected(mag, roll, pitch)
        return np.hypot(c[:, 0], c[:, 1]) - 1.0

    def to_dict(self) -> dict[str, Any]:
        return {
            "hard_iron": self.hard_iron.tolist(),
            "soft_iron": self.soft_iron.tolist(),
            "vertical_ratio": self.vertical_ratio,
            "horizontal_field": self.horizontal_field,
            "levelled": self.levelled,
            "n": self.n,
            "coverage_deg": self.coverage_deg,
            "residual_sigma": self.residual_sigma,
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
    """Algebraic ellipse through 2-D points (on normalised data): (centre (2,), S (2x2
    symmetric)) with ``|S (p - centre)| = 1`` for points on the ellipse."""
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
    return mu + scale * ctr, _sym_sqrt(m / k) / scale


def heading_coverage_deg(heading_rad: np.ndarray, bin_deg: float = 10.0) -> float:
    """How much of the circle the headings cover, in degrees (bins of ``bin_deg`` hit)."""
    h = np.mod(np.degrees(np.asarray(heading_rad, dtype=float)), 360.0)
    bins = np.unique(np.floor(h / bin_deg).astype(int))
    return float(bins.size * bin_deg)


_IU = np.triu_indices(3)


def fit_ellipsoid(xyz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Algebraic ellipsoid through 3-D points: (centre (3,), S (3x3 symmetric)) with
    ``|S (p - centre)| = 1`` on the ellipsoid."""
    p = np.asarray(xyz, dtype=float)
    mu = p.mean(axis=0)
    scale = float(np.sqrt(np.mean(np.sum((p - mu) ** 2, axis=1)))) or 1.0
    x, y, z = ((p - mu) / scale).T
    d = np.column_stack(
        [x * x, y * y, z * z, 2 * x * y, 2 * x * z, 2 * y * z, 2 * x, 2 * y, 2 * z,
         np.ones_like(x)]
    )
    w = np.linalg.svd(d, full_matrices=False)[2][-1]
    m = np.array([[w[0], w[3], w[4]], [w[3], w[1], w[5]], [w[4], w[5], w[2]]])
    g, f = w[6:9], w[9]
    if np.trace(m) < 0:
        m, g, f = -m, -g, -f
    if np.any(np.linalg.eigvalsh(m) <= 0):
        raise AnalysisError("the magnetometer samples do not lie on an ellipsoid")
    ctr = np.linalg.solve(m, -g)
    k = ctr @ m @ ctr - f
    if k <= 0:
        raise AnalysisError("the magnetometer ellipsoid fit is degenerate")
    return mu + scale * ctr, _sym_sqrt(m / k) / scale


def _unpack(w: np.ndarray) -> np.ndarray:
    s = np.zeros((3, 3))
    s[_IU] = w
    return s + np.triu(s, 1).T


def fit_magnetometer(
    mag: np.ndarray,
    roll: np.ndarray | None = None,
    pitch: np.ndarray | None = None,
    *,
    min_coverage_deg: float = MIN_COVERAGE_DEG,
) -> MagCalibration:
    """Fit the hard and soft iron of raw magnetometer samples (n, 3) in body FLU axes.

    Parameters
    ----------
    mag:
        Raw samples, any unit (the field strength is fitted).
    roll, pitch:
        Attitude (rad) at the samples, for tilt compensation; None: level.
    min_coverage_deg:
        Refuse (:class:`AnalysisError`) when the corrected headings cover less
        of the circle: the ellipse is then not determined.
    """
    from scipy.optimize import least_squares

    m = np.asarray(mag, dtype=float)
    if m.ndim != 2 or m.shape[1] != 3:
        raise OptionError("magnetometer samples must be an (n, 3) array")
    levelled = roll is not None and pitch is not None
    ok = np.isfinite(m).all(axis=1)
    r_ = np.zeros(m.shape[0]) if roll is None else np.asarray(roll, dtype=float)
    p_ = np.zeros(m.shape[0]) if pitch is None else np.asarray(pitch, dtype=float)
    ok &= np.isfinite(r_) & np.isfinite(p_)
    m, r_, p_ = m[ok], r_[ok], p_[ok]
    if m.shape[0] < MIN_SAMPLES:
        raise AnalysisError(
            f"the magnetometer calibration needs at least {MIN_SAMPLES} samples, got {m.shape[0]}"
        )
    lev = level_vectors(m, r_, p_)
    starts: list[tuple[np.ndarray, np.ndarray]] = []
    ctr, s2 = fit_ellipse(lev[:, :2])
    s3 = np.eye(3) * float(np.sqrt(np.linalg.det(s2)))
    s3[:2, :2] = s2
    starts.append((np.array([ctr[0], ctr[1], 0.0]), s3))
    spread = np.linalg.svd(m - m.mean(axis=0), compute_uv=False)
    if levelled and spread[2] > 0.1 * spread[0]:
        # samples spanning 3-D (large tilts): also start from the ellipsoid of the raw samples
        try:
            h0, e3 = fit_ellipsoid(m)
        except AnalysisError:
            pass
        else:
            ce = level_vectors((m - h0) @ e3.T, r_, p_)
            starts.append((h0, e3 / float(np.median(np.hypot(ce[:, 0], ce[:, 1])))))
    h0, s3 = starts[0]
    c0 = level_vectors((m - h0) @ s3.T, r_, p_)
    cover = heading_coverage_deg(np.arctan2(c0[:, 1], c0[:, 0]))
    if cover < min_coverage_deg:
        raise AnalysisError(
            f"the drive turns through {cover:.0f} deg of heading only; an ellipse fit of the "
            f"magnetometer needs {min_coverage_deg:.0f} deg or more (drive a full circle, give a "
            "swing calibration file, heading.deviation_deg, or fit to the GNSS course explicitly)"
        )
    best = None
    for h0, s3 in starts:
        c0 = level_vectors((m - h0) @ s3.T, r_, p_)
        v0 = np.concatenate([h0, s3[_IU], [float(np.median(c0[:, 2]))]])
        det2 = float(np.sqrt(np.linalg.det(s3[:2, :2])))
        # The vertical hard iron and the vertical row of the soft iron show only through
        # tilt changes: a weak pull towards the start keeps them defined on a level drive.
        scale = np.concatenate([np.full(3, 1.0 / det2), np.full(6, det2)])
        weak = np.array([2, 5, 7, 8])  # hz, S[0,2], S[1,2], S[2,2] in v
        lam = 1e-3 * math.sqrt(m.shape[0])

        def resid(v: np.ndarray, v0: np.ndarray = v0, scale: np.ndarray = scale,
                  weak: np.ndarray = weak, lam: float = lam) -> np.ndarray:
            c = level_vectors((m - v[:3]) @ _unpack(v[3:9]).T, r_, p_)
            pull = lam * (v[weak] - v0[weak]) / scale[weak]
            return np.concatenate([np.hypot(c[:, 0], c[:, 1]) - 1.0, c[:, 2] - v[9], pull])

        sol = least_squares(resid, v0, method="lm")
        if np.all(np.linalg.eigvalsh(_unpack(sol.x[3:9])) > 0) and (
            best is None or sol.cost < best.cost
        ):
            best = sol
    if best is None:
        raise AnalysisError(
            "the magnetometer fit did not converge to a soft-iron correction (does the drive "
            f"turn through {min_coverage_deg:.0f} deg or more?)"
        )
    v = best.x
    s = _unpack(v[3:9])
    if np.any(np.linalg.eigvalsh(s) <= 0):
        raise AnalysisError("the magnetometer fit did not converge to a soft-iron correction")
    c = level_vectors((m - v[:3]) @ s.T, r_, p_)
    radial = np.hypot(c[:, 0], c[:, 1]) - 1.0
    cover = heading_coverage_deg(np.arctan2(c[:, 1], c[:, 0]))
    notes: list[str] = []
    if not levelled:
        notes.append("no attitude: the vehicle is taken as level; its tilt during the drive "
                     "is part of the residual")
    sigma = 1.4826 * float(np.median(np.abs(radial - np.median(radial))))
    return MagCalibration(
        hard_iron=v[:3].copy(),
        soft_iron=s,
        vertical_ratio=float(v[9]),
        horizontal_field=1.0 / float(np.cbrt(abs(np.linalg.det(s)))),
        levelled=levelled,
        n=int(m.shape[0]),
        coverage_deg=cover,
        residual_sigma=max(sigma, 1e-12),
        residual_rms=float(np.sqrt(np.mean(radial**2))),
        residual_max=float(np.max(np.abs(radial))),
        notes=notes,
    )
