"""Procedural clothing textures as per-face albedo, evaluated on the rest (T-pose) body so that
garments and patterns stick to the skin whatever the pose.

The paper textures its bodies with 917 SURREAL / MultiGarmentNet scans; we cannot ship those, so
each body gets a random outfit instead. What matters downstream (Canny edges) is that garment
boundaries, patterns, hair and shoes produce edges inside the silhouette the way clothes do:

- regions: a top (torso, plus the arms up to a sampled sleeve length: sleeveless, short or long),
  a bottom (hips and legs down to a sampled hem: shorts, knee length or full length), shoes (or
  bare feet), hair (top and back of the head, or bald), and skin everywhere else (face, neck,
  hands, uncovered limbs). 10% of outfits use one garment for top and bottom (a jumpsuit).
- colours: garments from random HSV (30% near-neutral: black, white, grey), skin from six tones
  from light to dark, hair from a natural palette, shoes mostly dark; all with small jitter.
- patterns per garment, from the face's rest-pose centre: plain (45%), stripes (20%, random
  direction biased to horizontal, period 3-15 cm), checks (15%) and blotchy noise (20%, sum of
  three random 3D sinusoids, thresholded), each in two colours.
- a fraction of bodies (``grey_fraction``, default 10%) get a uniform grey albedo (level in
  [0.4, 0.8]) instead: the paper's "grey texture" share. The paper gives no number; 10% is our
  choice.

Regions are found from the part labels (SMPL joint groups) and rest-pose coordinates (Y up, arms
along ±X in the T-pose), with landmarks (shoulder, elbow, wrist, waist, knee, ankle, neck, head)
measured from the given rest vertices, so any SMPL-like body in a T-pose works.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import torch

GREY_FRACTION = 0.1
"""Default share of bodies with a uniform grey texture (our choice; not stated in the paper)."""

# SMPL joint groups (part labels) used for the garment regions.
TORSO_PARTS = (0, 3, 6, 9, 13, 14)
UPPER_ARM_PARTS = (16, 17)
FOREARM_PARTS = (18, 19)
HAND_PARTS = (20, 21, 22, 23)
THIGH_PARTS = (1, 2)
SHIN_PARTS = (4, 5)
FOOT_PARTS = (7, 8, 10, 11)
NECK_PART = 12
HEAD_PART = 15

SKIN_TONES = (
    (0.96, 0.80, 0.69),
    (0.92, 0.72, 0.58),
    (0.80, 0.58, 0.42),
    (0.65, 0.45, 0.31),
    (0.47, 0.31, 0.20),
    (0.30, 0.20, 0.13),
)
HAIR_COLOURS = (
    (0.05, 0.04, 0.04),
    (0.20, 0.13, 0.08),
    (0.38, 0.25, 0.15),
    (0.75, 0.62, 0.38),
    (0.55, 0.55, 0.55),
    (0.55, 0.25, 0.10),
)

PATTERN_PROBABILITIES = (0.45, 0.20, 0.15, 0.20)
"""Plain, stripes, checks, noise."""
SLEEVE_PROBABILITIES = (0.2, 0.45, 0.35)
"""Sleeveless, short, long."""
HEM_PROBABILITIES = (0.3, 0.15, 0.55)
"""Shorts, knee length, full length."""
JUMPSUIT_PROBABILITY = 0.1
SHOE_PROBABILITY = 0.85
BALD_PROBABILITY = 0.1
NEUTRAL_GARMENT_PROBABILITY = 0.3


def _member(labels: torch.Tensor, parts: tuple[int, ...]) -> torch.Tensor:
    return torch.isin(labels, torch.tensor(parts, device=labels.device))


class _Draws:
    """The random numbers of one :meth:`ClothingTextureSampler.sample` call, ``count`` at a time,
    drawn on ``device`` from ``generator``."""

    def __init__(self, count: int, generator: torch.Generator | None, device: torch.device) -> None:
        self.count, self.generator, self.device = count, generator, device

    def uniform(self, low: float, high: float) -> torch.Tensor:
        """``(count,)`` uniform in ``[low, high)``."""
        return low + (high - low) * torch.rand(
            (self.count,), generator=self.generator, device=self.device
        )

    def choice(self, probabilities: tuple[float, ...]) -> torch.Tensor:
        """``(count,)`` long indices drawn with these probabilities."""
        weights = torch.tensor(probabilities, device=self.device)
        return torch.multinomial(weights, self.count, replacement=True, generator=self.generator)


@dataclass(frozen=True)
class _Outfit:
    """Each body's garment geometry, ``(B, 1)`` rest-pose coordinates in metres (SMPL axes) or
    yes/no flags.

    Attributes:
        sleeve_end: distance from the body's axis (``|x|``) where sleeves end.
        hem_height, waist, neckline, hairline, hair_nape: heights (``y``).
        hair_back: depth (``z``) in front of which the back of the head has no hair.
        turtleneck, jumpsuit, shoes, bald: bool flags.
    """

    sleeve_end: torch.Tensor
    hem_height: torch.Tensor
    waist: torch.Tensor
    neckline: torch.Tensor
    turtleneck: torch.Tensor
    jumpsuit: torch.Tensor
    shoes: torch.Tensor
    bald: torch.Tensor
    hairline: torch.Tensor
    hair_back: torch.Tensor
    hair_nape: torch.Tensor

    def to(self, device: torch.device) -> _Outfit:
        return _Outfit(**{f.name: getattr(self, f.name).to(device) for f in fields(self)})


class ClothingTextureSampler:
    """Random outfits as per-face albedo for one mesh topology.

    Args:
        rest_vertices: ``(V, 3)`` rest T-pose vertices in metres, SMPL axes (Y up, facing +Z,
            arms along ±X), e.g. ``BodyModel().v_template``.
        faces: ``(F, 3)`` long vertex indices.
        part_labels: ``(V,)`` long SMPL joint-group label of each vertex (0..23).
        grey_fraction: share of bodies with a uniform grey texture.
    """

    def __init__(
        self,
        rest_vertices: torch.Tensor,
        faces: torch.Tensor,
        part_labels: torch.Tensor,
        grey_fraction: float = GREY_FRACTION,
    ) -> None:
        if rest_vertices.dim() != 2 or rest_vertices.shape[1] != 3:
            raise ValueError(f"rest_vertices must be (V, 3), got {tuple(rest_vertices.shape)}")
        if part_labels.shape != (rest_vertices.shape[0],):
            raise ValueError(
                f"part_labels must be ({rest_vertices.shape[0]},), got {tuple(part_labels.shape)}"
            )
        if not 0.0 <= grey_fraction <= 1.0:
            raise ValueError(f"grey_fraction must be in [0, 1], got {grey_fraction}")
        present = set(torch.unique(part_labels).tolist())
        missing = {HEAD_PART, NECK_PART, *TORSO_PARTS[:1], *UPPER_ARM_PARTS, *SHIN_PARTS} - present
        if missing:
            raise ValueError(
                f"part_labels lacks SMPL joint groups {sorted(missing)}; the clothing regions "
                "need SMPL's 24 groups (0 pelvis ... 23 right hand)"
            )
        self.grey_fraction = grey_fraction
        rest = rest_vertices.detach().to(torch.float32).cpu()
        labels = part_labels.detach().cpu().long()
        faces = faces.detach().cpu().long()
        self.num_faces = faces.shape[0]
        centre = rest[faces].mean(dim=1)  # (F, 3)
        face_part = labels[faces[:, 0]]

        def extent(parts: tuple[int, ...], axis: int, reduce: str, absolute: bool = False):
            values = rest[_member(labels, parts), axis]
            values = values.abs() if absolute else values
            return float(values.min() if reduce == "min" else values.max())

        self.landmarks = {
            "shoulder": extent(UPPER_ARM_PARTS, 0, "min", absolute=True),
            "elbow": extent(FOREARM_PARTS, 0, "min", absolute=True),
            "wrist": extent(HAND_PARTS, 0, "min", absolute=True),
            "waist": extent((3,), 1, "min"),
            "crotch": extent(THIGH_PARTS, 1, "max"),
            "knee": extent(SHIN_PARTS, 1, "max"),
            "ankle": extent(FOOT_PARTS, 1, "max"),
            "neck": extent((NECK_PART,), 1, "min"),
            "head_top": extent((HEAD_PART,), 1, "max"),
        }
        head = rest[labels == HEAD_PART]
        self.head_centre = head.mean(dim=0)

        self.centre = centre
        self.is_torso = _member(face_part, TORSO_PARTS)
        self.is_arm = _member(face_part, UPPER_ARM_PARTS + FOREARM_PARTS)
        self.is_leg = _member(face_part, THIGH_PARTS + SHIN_PARTS)
        self.is_foot = _member(face_part, FOOT_PARTS)
        self.is_neck = face_part == NECK_PART
        self.is_head = face_part == HEAD_PART
        self.arm_reach = centre[:, 0].abs()
        self._device_cache: dict[torch.device, dict[str, torch.Tensor]] = {}

    def _features(self, device: torch.device) -> dict[str, torch.Tensor]:
        if device not in self._device_cache:
            names = ("centre", "is_torso", "is_arm", "is_leg", "is_foot", "is_neck", "is_head")
            cache = {name: getattr(self, name).to(device) for name in names}
            cache["arm_reach"] = self.arm_reach.to(device)
            self._device_cache[device] = cache
        return self._device_cache[device]

    def sample(
        self,
        count: int,
        generator: torch.Generator | None = None,
        device: torch.device | str = "cpu",
    ) -> torch.Tensor:
        """Random outfits.

        Args:
            count: number of bodies B.
            generator: torch random generator (None: the global one); the random numbers are
                drawn on its device (a CPU generator works for CUDA output too).
            device: where the albedo is made.

        Returns:
            ``(B, F, 3)`` float32 albedo in [0, 1].
        """
        device = torch.device(device)
        draws = _Draws(count, generator, generator.device if generator is not None else device)
        outfit = self._draw_outfit(draws)
        table = self._draw_colour_table(draws, outfit.jumpsuit)
        top_pattern = self._pattern_parameters(count, generator, draws.device)
        bottom_pattern = self._pattern_parameters(count, generator, draws.device)
        bottom_pattern = {
            name: torch.where(outfit.jumpsuit.view((count,) + (1,) * (value.dim() - 1)), top, value)
            for (name, value), top in zip(bottom_pattern.items(), top_pattern.values(), strict=True)
        }
        # Per-body parameters to the output device; per-face work happens there.
        outfit, table = outfit.to(device), table.to(device)
        top_pattern = {name: value.to(device) for name, value in top_pattern.items()}
        bottom_pattern = {name: value.to(device) for name, value in bottom_pattern.items()}
        centre = self._features(device)["centre"]
        top_bit = self._pattern_bits(top_pattern, centre)
        code = self._face_codes(outfit, top_bit, self._pattern_bits(bottom_pattern, centre))
        code = code.long() + torch.arange(count, device=device)[:, None] * table.shape[1]
        albedo = table.reshape(-1, 3).clamp(0.0, 1.0).index_select(0, code.view(-1))
        return albedo.view(count, self.num_faces, 3)

    def _draw_outfit(self, draws: _Draws) -> _Outfit:
        """Each body's garment geometry: sleeve, hem, waist, neckline, shoes and hair."""
        marks = self.landmarks
        sleeve = draws.choice(SLEEVE_PROBABILITIES)
        sleeve_end = torch.stack(
            (
                marks["shoulder"] - draws.uniform(0.0, 0.02),
                marks["shoulder"] + draws.uniform(0.04, 0.14),
                marks["wrist"] - draws.uniform(0.0, 0.04),
            ),
            dim=1,
        ).gather(1, sleeve[:, None])
        hem = draws.choice(HEM_PROBABILITIES)
        hem_height = torch.stack(
            (
                marks["crotch"] - draws.uniform(0.05, 0.25),
                marks["knee"] + draws.uniform(-0.06, 0.06),
                marks["ankle"] + draws.uniform(-0.02, 0.03),
            ),
            dim=1,
        ).gather(1, hem[:, None])
        return _Outfit(
            sleeve_end=sleeve_end,
            hem_height=hem_height,
            waist=marks["waist"] + draws.uniform(-0.08, 0.04)[:, None],
            neckline=marks["neck"] - draws.uniform(0.0, 0.12)[:, None],
            turtleneck=draws.uniform(0.0, 1.0)[:, None] < 0.1,
            jumpsuit=draws.uniform(0.0, 1.0)[:, None] < JUMPSUIT_PROBABILITY,
            shoes=draws.uniform(0.0, 1.0)[:, None] < SHOE_PROBABILITY,
            bald=draws.uniform(0.0, 1.0)[:, None] < BALD_PROBABILITY,
            hairline=marks["head_top"] - draws.uniform(0.03, 0.10)[:, None],
            hair_back=self.head_centre[2].item() + draws.uniform(-0.06, 0.02)[:, None],
            hair_nape=marks["neck"] + draws.uniform(0.02, 0.12)[:, None],
        )

    def _draw_colour_table(self, draws: _Draws, jumpsuit: torch.Tensor) -> torch.Tensor:
        """``(B, 7, 3)`` each body's colours: skin, top (2 colours), bottom (2), hair, shoes
        (one grey level throughout for the grey share)."""
        count, generator, draw = draws.count, draws.generator, draws.device
        skin = self._palette(SKIN_TONES, count, 0.04, generator, draw)
        hair = self._palette(HAIR_COLOURS, count, 0.04, generator, draw)
        shoe_colour = self._random_colours(count, generator, draw, neutral=0.7)
        top_colours = self._random_colours(2 * count, generator, draw, NEUTRAL_GARMENT_PROBABILITY)
        bottom_colours = self._random_colours(
            2 * count, generator, draw, NEUTRAL_GARMENT_PROBABILITY
        )
        top_colours, bottom_colours = (
            top_colours.view(count, 2, 3),
            bottom_colours.view(count, 2, 3),
        )
        bottom_colours = torch.where(jumpsuit[..., None], top_colours, bottom_colours)
        table = torch.cat(
            (skin[:, None], top_colours, bottom_colours, hair[:, None], shoe_colour[:, None]), dim=1
        )
        grey = draws.uniform(0.0, 1.0) < self.grey_fraction
        grey_level = draws.uniform(0.4, 0.8)[:, None, None].expand_as(table)
        return torch.where(grey[:, None, None], grey_level, table)

    def _face_codes(
        self, outfit: _Outfit, top_bit: torch.Tensor, bottom_bit: torch.Tensor
    ) -> torch.Tensor:
        """``(B, F)`` uint8 row of each face in its body's colour table: 0 skin, 1-2 top, 3-4
        bottom, 5 hair, 6 shoes (``top_bit``, ``bottom_bit``: the patterns' ``(B, F)`` 0/1)."""
        features = self._features(top_bit.device)
        centre = features["centre"]
        # Regions (B, F); they are disjoint, so the colour code is a sum.
        height = centre[:, 1][None]
        covered_arm = features["is_arm"] & (features["arm_reach"][None] <= outfit.sleeve_end)
        upper_torso = features["is_torso"] & (height >= outfit.waist)
        in_top = covered_arm | (upper_torso & (height <= outfit.neckline))
        in_top |= outfit.turtleneck & features["is_neck"]
        covered_leg = features["is_leg"] & (height >= outfit.hem_height)
        in_bottom = covered_leg | (features["is_torso"] & (height < outfit.waist))
        behind_head = (centre[:, 2][None] < outfit.hair_back) & (height > outfit.hair_nape)
        in_hair = features["is_head"] & ((height > outfit.hairline) | behind_head) & ~outfit.bald
        in_shoes = features["is_foot"] & outfit.shoes
        byte = torch.uint8
        code = in_top.to(byte) * (top_bit + 1)
        code += in_bottom.to(byte) * (bottom_bit + 3)
        code += in_hair.to(byte) * 5
        code += in_shoes.to(byte) * 6
        return code

    # --- colours and patterns ---------------------------------------------------------------

    @staticmethod
    def _palette(
        palette: tuple[tuple[float, float, float], ...],
        count: int,
        jitter: float,
        generator: torch.Generator | None,
        device: torch.device,
    ) -> torch.Tensor:
        colours = torch.tensor(palette, device=device)
        pick = torch.randint(len(palette), (count,), generator=generator, device=device)
        noise = (torch.rand(count, 3, generator=generator, device=device) * 2 - 1) * jitter
        return (colours[pick] + noise).clamp(0.0, 1.0)

    @staticmethod
    def _random_colours(
        count: int, generator: torch.Generator | None, device: torch.device, neutral: float
    ) -> torch.Tensor:
        """``(count, 3)`` colours from random HSV, a ``neutral`` share nearly unsaturated."""
        hue = torch.rand(count, generator=generator, device=device)
        saturation = torch.rand(count, generator=generator, device=device) * 0.9
        value = 0.08 + 0.87 * torch.rand(count, generator=generator, device=device)
        is_neutral = torch.rand(count, generator=generator, device=device) < neutral
        saturation = torch.where(is_neutral, saturation * 0.1, saturation)
        # HSV to RGB: channel k = v - v*s*clamp(min(h', 4-h'), 0, 1) with h' = (6h + n_k) mod 6.
        offsets = torch.tensor((5.0, 3.0, 1.0), device=device)
        shifted = torch.remainder(hue[:, None] * 6.0 + offsets, 6.0)
        ramp = torch.minimum(shifted, 4.0 - shifted).clamp(0.0, 1.0)
        return value[:, None] * (1.0 - saturation[:, None] * ramp)

    @staticmethod
    def _pattern_parameters(
        count: int, generator: torch.Generator | None, device: torch.device
    ) -> dict[str, torch.Tensor]:
        """Pattern kind (0 plain, 1 stripes, 2 checks, 3 noise), three directions scaled by
        their spatial frequency ``(B, 3, 3)`` (1/m), phases ``(B, 3)`` and a threshold ``(B,)``."""
        kind = torch.multinomial(
            torch.tensor(PATTERN_PROBABILITIES, device=device),
            count,
            replacement=True,
            generator=generator,
        )
        directions = torch.randn(count, 3, 3, generator=generator, device=device)
        # Stripes biased to horizontal bands (along Y); checks use two orthogonal directions.
        directions[:, 0, 1] += 2.5 * torch.sign(directions[:, 0, 1])
        directions = torch.nn.functional.normalize(directions, dim=-1)
        across = (
            directions[:, 1]
            - (directions[:, 1] * directions[:, 0]).sum(-1, True) * (directions[:, 0])
        )
        directions[:, 1] = torch.nn.functional.normalize(across, dim=-1)
        period = 0.05 + 0.10 * torch.rand(count, 3, generator=generator, device=device)
        noise_period = 0.08 + 0.22 * torch.rand(count, 3, generator=generator, device=device)
        period = torch.where((kind == 3)[:, None], noise_period, period)
        return {
            "kind": kind,
            "frequency": directions / period[..., None],
            "phase": torch.rand(count, 3, generator=generator, device=device),
            "threshold": 0.6 * torch.rand(count, generator=generator, device=device) - 0.3,
        }

    @staticmethod
    def _pattern_bits(parameters: dict[str, torch.Tensor], centre: torch.Tensor) -> torch.Tensor:
        """``(B, F)`` uint8 0/1: the garment colour of each face.

        With ``u_k = c · d_k / p_k + φ_k`` (c the face's rest-pose centre): stripes
        ``frac(u_1) < duty``, checks ``(frac(u_1) < ½) xor (frac(u_2) < ½)``, noise
        ``Σ_k sin(2π u_k) > t``; plain is 0. Only the bodies wearing a pattern pay for it.
        """
        kind = parameters["kind"]
        bits = torch.zeros(kind.shape[0], centre.shape[0], dtype=torch.uint8, device=centre.device)
        for pattern, waves_needed in ((1, 1), (2, 2), (3, 3)):
            bodies = (kind == pattern).nonzero().squeeze(1)
            if bodies.numel() == 0:
                continue
            frequency = parameters["frequency"][bodies, :waves_needed]
            waves = torch.einsum("fc,bkc->bkf", centre, frequency)
            waves += parameters["phase"][bodies, :waves_needed, None]
            threshold = parameters["threshold"][bodies, None]
            if pattern == 1:
                value = (waves[:, 0] - waves[:, 0].floor()) < 0.5 + threshold
            elif pattern == 2:
                halves = (waves - waves.floor()) < 0.5
                value = halves[:, 0] ^ halves[:, 1]
            else:
                value = torch.sin(2.0 * torch.pi * waves).sum(dim=1) > threshold
            bits[bodies] = value.to(torch.uint8)
        return bits
