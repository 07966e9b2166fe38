"""``EvidenceConfig``: the few numbers that set how strongly 2D keypoints update the prior.

They depend on the network (how over- or under-confident it is), so the tuned ones travel with
its weights: ``hkpd-tune-evidence --write-to`` stores :meth:`EvidenceConfig.to_dict` in the
checkpoint (``hkpd.network.checkpoint``: a plain dict, as the network layer knows no
conditioning), and ``Predictor.from_pretrained`` reads it back with
:meth:`EvidenceConfig.from_dict`; a checkpoint without one gets the defaults below.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, fields, replace

_RIGID_SPREADS = ("conditional", "shape", "marginal")


@dataclass(frozen=True)
class EvidenceConfig:
    """Settings of the keypoint-evidence posterior (``docs/evidence.md`` says how each was chosen).

    Attributes:
        prior_weight: temperature ``w`` on the network's log-density: the posterior is
            ``p_net(pose, shape)^w × L(keypoints | body)``. Below 1 the network's
            (over-confident) distribution counts for less than its face value.
        keypoint_sigma: standard deviation of one detected keypoint coordinate about the body
            model's keypoint, as a fraction of the crop's side (the crop is 1.2× the person's
            extent, so 0.03 is about 3.6 % of the person's height).
        robust_scale: the Cauchy loss turns from quadratic to logarithmic at this many sigmas,
            so a keypoint the detector put on the wrong limb pulls only weakly.
        min_keypoints: with fewer evidence keypoints the fit is not attempted (the network's
            own distribution is returned, with the reason).
        global_rotation_sigma: radians; weak prior that keeps the global rotation near its
            start (the network predicts a point, not a distribution, for it).
        camera_sigma: weak prior on the camera's log scale and translation (metres) about the
            start's.
        max_iterations: Levenberg-Marquardt iterations at most.
        tolerance: stop when an accepted step lowers the cost by less than this fraction.
        joint_spread: ``"conditional"`` (the default) gives each joint its precision given the
            other joints (the diagonal blocks of the posterior precision: the best independent
            approximation in the mode-seeking sense, every sample consistent with the evidence);
            ``"marginal"`` its marginal precision (evidence shared along a chain counted once
            per chain, but samples drawn joint by joint then scatter the limb ends).
            ``docs/evidence.md`` says how the defaults were chosen.
        rigid_spread: how the Laplace step treats the global rotation and the camera, which
            the samples keep fixed: ``"conditional"`` holds them at the fit (the pose and
            shape precisions are the blocks of the Hessian given them, so height cannot trade
            off against the camera's scale), ``"shape"`` marginalises them for the shape
            Gaussian (the Schur complement of their block: the shape's spread as if they were
            unknown; the joints as with ``"conditional"``), ``"marginal"`` for the joints' too.
            The default stays ``"conditional"``: ``"shape"`` makes β₀'s spread honest (z² 3.5 ->
            0.6) but its height spread reaches every vertex and dilutes what hiding a limb does
            (synthetic covered-limb ratio 1.74 -> 1.49, photos 1.89 -> 1.88; ``docs/shape.md``).
        facings: ``2`` (the default) fits every start twice, as the network read it and turned
            180° about the body's vertical axis (:mod:`hkpd.conditioning.facing`), and keeps
            the lower cost: a person seen from behind is no longer read facing the camera.
            ``1`` fits the starts as read (the fit before issue 42).
        unread_joint_weight: the prior weight of a joint that no evidence term reads (every
            keypoint and landmark below it hidden or missing:
            :mod:`hkpd.conditioning.evidence_reach`). 1 (the default) keeps the network's own
            spread there: ``prior_weight`` tempers the network because it saw the keypoints the
            fit weighs again, which a hidden limb's were not. Equal to ``prior_weight``: every
            joint tempered alike (before issue 58; a hidden forearm's hand was then 1.3× less
            sure with the evidence than from the network alone).
    """

    prior_weight: float = 0.5
    keypoint_sigma: float = 0.03
    robust_scale: float = 3.0
    min_keypoints: int = 4
    global_rotation_sigma: float = 0.5
    camera_sigma: float = 0.5
    max_iterations: int = 30
    tolerance: float = 1e-6
    joint_spread: str = "conditional"
    rigid_spread: str = "conditional"
    facings: int = 2
    unread_joint_weight: float = 1.0

    def __post_init__(self) -> None:
        positive = {
            "prior_weight": self.prior_weight,
            "unread_joint_weight": self.unread_joint_weight,
            "keypoint_sigma": self.keypoint_sigma,
            "robust_scale": self.robust_scale,
            "global_rotation_sigma": self.global_rotation_sigma,
            "camera_sigma": self.camera_sigma,
            "tolerance": self.tolerance,
        }
        for name, value in positive.items():
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"EvidenceConfig.{name} must be a positive number, got {value}")
        spreads = {"joint_spread": ("marginal", "conditional"), "rigid_spread": _RIGID_SPREADS}
        for name, allowed in spreads.items():
            if getattr(self, name) not in allowed:
                choices = ", ".join(map(repr, allowed[:-1])) + f" or {allowed[-1]!r}"
                raise ValueError(
                    f"EvidenceConfig.{name} must be {choices}, got {getattr(self, name)!r}"
                )
        if self.min_keypoints < 1 or self.max_iterations < 1:
            raise ValueError("EvidenceConfig.min_keypoints and max_iterations must be >= 1")
        if self.facings not in (1, 2):
            raise ValueError(
                f"EvidenceConfig.facings must be 1 (as read) or 2 (also half-turned), "
                f"got {self.facings}"
            )

    def for_mask_evidence(self) -> EvidenceConfig:
        """These settings for a fit that also weighs a person mask (the silhouette term).

        With a mask the fit pins height to the outline at the fit's camera scale, and holding
        the camera fixed makes β₀ four to nine times too sure (z² 6-9 on synthetic views with
        measured-noise masks): a 2D outline cannot tell a tall person far away from a short
        one close by. So ``rigid_spread="conditional"`` becomes ``"shape"`` (the camera and
        global rotation marginalised for the shape Gaussian, the joints unchanged); the other
        settings, and an explicit ``"shape"`` or ``"marginal"``, are kept.
        """
        if self.rigid_spread != "conditional":
            return self
        return replace(self, rigid_spread="shape")

    def to_dict(self) -> dict[str, float | int | str]:
        """Every setting by field name: plain data, as a checkpoint stores it."""
        return asdict(self)

    @classmethod
    def from_dict(cls, values: Mapping[str, object], source: str) -> EvidenceConfig:
        """The settings ``values`` names (the defaults for the others), as stored in ``source``
        (a checkpoint's path: every error names it).

        Raises:
            ValueError: a name that is not a setting (nothing is ignored silently: a setting
                this version does not know would change the posterior), a value of the wrong
                type, or one the config refuses.
        """
        defaults = cls()
        known = {field.name for field in fields(cls)}
        unknown = sorted(set(values) - known)
        if unknown:
            raise ValueError(
                f"{source}: unknown evidence setting(s) {unknown} (this hkpd knows "
                f"{sorted(known)}); store the settings again with hkpd-tune-evidence --write-to"
            )
        chosen = {
            name: _stored_value(name, getattr(defaults, name), value, source)
            for name, value in values.items()
        }
        try:
            return replace(defaults, **chosen)
        except ValueError as error:
            raise ValueError(f"{source}: {error}") from error


def _stored_value(
    name: str, default: float | int | str, value: object, source: str
) -> float | int | str:
    """``value`` as the type of the setting ``name`` (whose default is ``default``).

    Raises:
        ValueError: naming ``source``, when ``value`` is not of that type (booleans never are;
            an integer counts as a float, a whole float as an integer).
    """
    if not isinstance(value, bool):
        if isinstance(default, str) and isinstance(value, str):
            return value
        if isinstance(default, float) and isinstance(value, int | float):
            return float(value)
        if (
            isinstance(default, int)
            and isinstance(value, int | float)
            and float(value).is_integer()
        ):
            return int(value)
    raise ValueError(f"{source}: evidence setting {name} must be like {default!r}, got {value!r}")
