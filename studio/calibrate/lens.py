"""Choose between the central and the dual-lens camera model by cross-validation.

A dual-fisheye 360° camera (e.g. a Ricoh Theta) sees each hemisphere from its own lens centre; the
dual-lens model (:class:`~studio.geometry.equirect.EquirectCamera` ``lens_offset = b``: lens centres at
``(±b, 0, 0)`` in the camera frame) adds one parameter to the pose. :func:`choose_lens_model` fits both
models, cross-validates both with the same folds, and keeps the dual-lens one only when it pays off:

* its held-out column error (mean over the inliers) is at least 10 % and at least 0.1 px lower than the
  central model's;
* the fitted ``|b|`` is at most 5 cm (a camera's lenses, not a wrong pose);
* ``b`` is determined: its 1σ from the Jacobian at the fit's own noise level is at most 1 cm.

Otherwise (or when the dual-lens fit fails) the central model is kept, with the reason.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from numpy.typing import ArrayLike

from studio.calibrate.extrinsics import CalibrationError, CrossValidation, cross_validate

__all__ = [
    "MAX_LENS_OFFSET_M",
    "MAX_LENS_STD_M",
    "MIN_GAIN",
    "MIN_GAIN_PX",
    "LensChoice",
    "choose_lens_model",
]

MIN_GAIN = 0.10  # the dual-lens model's held-out column mean must be at least this fraction lower
MIN_GAIN_PX = 0.1  # ... and at least this many pixels lower
MAX_LENS_OFFSET_M = 0.05  # largest plausible |b|, metres
MAX_LENS_STD_M = 0.01  # largest 1σ of b, metres


@dataclass(frozen=True, eq=False)
class LensChoice:
    """Both models' cross-validations and the kept one.

    Attributes:
        single: cross-validation of the central (single-centre) model.
        dual: cross-validation of the dual-lens model, or None when its fit failed.
        dual_kept: whether the dual-lens model was kept.
        reason: one line saying why.
    """

    single: CrossValidation
    dual: CrossValidation | None
    dual_kept: bool
    reason: str

    @property
    def kept(self) -> CrossValidation:
        """The cross-validation of the kept model."""
        return self.dual if self.dual_kept and self.dual is not None else self.single

    @property
    def lens_offset(self) -> float:
        """The kept model's lens offset, metres (0 for the central model)."""
        return self.kept.fit.lens_offset

    def to_json(self) -> dict[str, Any]:
        """The kept model's metrics plus ``col_px_mean_single`` / ``col_px_median_single`` and the dual's."""
        out = self.kept.to_json()
        s = self.single.to_json()
        out["col_px_mean_single"] = s["col_px_mean"]
        out["col_px_median_single"] = s["col_px_median"]
        if self.dual is not None:
            d = self.dual.to_json()
            out["col_px_mean_dual"] = d["col_px_mean"]
            out["col_px_median_dual"] = d["col_px_median"]
            out["lens_offset_fitted_m"] = d["lens_offset_m"]
            out["lens_offset_std_m"] = round(self.dual.fit.lens_offset_std, 6)
        out["lens_model"] = "dual" if self.dual_kept else "single"
        return out


def _decide(single: CrossValidation, dual: CrossValidation) -> tuple[bool, str]:
    s = single.to_json()["col_px_mean"]
    d = dual.to_json()["col_px_mean"]
    b, b_std = dual.fit.lens_offset, dual.fit.lens_offset_std
    gain = (s - d) / s if s > 0 else 0.0
    than = "lower" if gain >= 0 else "higher"
    num = (
        f"held-out column mean {d:.2f} px vs {s:.2f} px central ({abs(gain):.0%} {than}), "
        f"b = {b * 100:+.2f} ± {b_std * 100:.2f} cm"
    )
    if not (gain >= MIN_GAIN and s - d >= MIN_GAIN_PX):
        return False, f"dual-lens model does not pay off: {num} (needs >= {MIN_GAIN:.0%} lower)"
    if not abs(b) <= MAX_LENS_OFFSET_M:
        return False, f"dual-lens model rejected: |b| above {MAX_LENS_OFFSET_M * 100:.0f} cm: {num}"
    if not b_std <= MAX_LENS_STD_M:
        return (
            False,
            f"dual-lens model rejected: b undetermined (1σ above {MAX_LENS_STD_M * 100:.0f} cm): {num}",
        )
    return True, f"dual-lens model kept: {num}"


def choose_lens_model(
    xyz: ArrayLike,
    uv: ArrayLike,
    *,
    image_size: tuple[int, int],
    folds: int = 5,
    seed: int = 0,
    labels: Sequence[str] | None = None,
    **fit_kwargs: Any,
) -> LensChoice:
    """Cross-validate the central and the dual-lens model and keep the better one (module docstring).

    Args:
        xyz: ``(N, 3)`` points, metres; uv: ``(N, 2)`` px; image_size: ``(W, H)`` px.
        folds: K of the K-fold cross-validation (the same folds for both models).
        seed: shuffles the fold assignment.
        labels: names of the rows in error messages.
        **fit_kwargs: passed to :func:`~studio.calibrate.extrinsics.fit_extrinsics` (not ``lens_offset``).

    Raises:
        CalibrationError: the central model cannot be fitted (bad input; the dual-lens model failing
            only keeps the central one).
    """
    if "lens_offset" in fit_kwargs:
        raise TypeError("choose_lens_model fits both lens models; do not pass lens_offset")
    kw: dict[str, Any] = {"image_size": image_size, "folds": folds, "seed": seed, "labels": labels}
    single = cross_validate(xyz, uv, lens_offset=0.0, **kw, **fit_kwargs)
    try:
        dual = cross_validate(xyz, uv, lens_offset=None, **kw, **fit_kwargs)
    except CalibrationError as exc:
        return LensChoice(single, None, False, f"dual-lens model could not be fitted ({exc})")
    if not math.isfinite(dual.fit.lens_offset_std):
        return LensChoice(single, dual, False, "dual-lens model rejected: b is not determined by the points")
    kept, reason = _decide(single, dual)
    return LensChoice(single, dual, kept, reason)
