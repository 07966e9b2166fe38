"""A scene file: everything needed to reopen an explorer scene, as one small JSON document.

It holds the photo (by path with its sha256 checksum, embedded as base64 when asked, the
shipped photo by name and checksum so the scene opens on any install, or the synthetic demo
scene), the person box, the occluder boxes, the concentration factors (per
joint, on all joints, on the shape spread), the evidence switches, the display settings, the
seed, the model's path and the compare setting. ``hkpd-explore PHOTO ... --save-scene FILE``
writes one, ``hkpd-explore --scene FILE`` and the panel's *Load scene* open one. An exported
page embeds the scene it shows (:data:`PAGE_SCENE_ID`), so a page opens as a scene too.

Pure data and checks: no viser, no torch. Every way a file can be wrong raises
:class:`SceneFileError` with a sentence saying what to do.
"""

from __future__ import annotations

import base64
import hashlib
import html
import json
import math
import re
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

from hkpd.explorer.colour_map import COLOURINGS
from hkpd.explorer.demo_photo import SHIPPED_PHOTO, shipped_photo
from hkpd.explorer.state import CONCENTRATION_EXPONENT_RANGE, MAX_DISPLAYED_SAMPLES, MAX_SAMPLES
from hkpd.explorer.upload import ALLOWED_SUFFIXES
from hkpd.kinematic_tree import BODY_JOINT_NAMES
from hkpd.stated_body import StatedBody

FORMAT = "hkpd-explorer-scene"
VERSION = 1
"""The file format's name and version (a file of another version is refused)."""

PAGE_SCENE_ID = "hkpd-scene"
"""``id`` of the ``<script type="application/json">`` element holding a page's scene."""

Box = tuple[float, float, float, float]

SHIPPED_PHOTO_NAME = "the shipped CC0 photo"
"""What captions call the shipped photo."""

_MAGIC_SUFFIXES = ((b"\xff\xd8\xff", ".jpg"), (b"\x89PNG", ".png"), (b"BM", ".bmp"),
                   (b"II*\x00", ".tif"), (b"MM\x00*", ".tif"))  # fmt: skip
"""A photo file's first bytes -> a suffix (WebP is checked apart: RIFF....WEBP)."""


class SceneFileError(ValueError):
    """A scene file that cannot be used; the message says why and what to do."""


@dataclass(frozen=True)
class PhotoRef:
    """Where a scene's photo comes from: exactly one of ``path``, ``embedded`` or ``demo``.

    Attributes:
        name: what captions call the photo (a file name, "the shipped CC0 photo").
        path: the photo file (absolute, or relative to the scene file's folder).
        sha256: hex digest of the photo file's bytes (or of the embedded bytes).
        embedded: base64 of the photo file's bytes (a JPEG or PNG).
        demo: ``"synthetic"``: the scene hkpd renders itself (no file); ``"shipped"``: the
            photo shipped in ``hkpd.assets`` (every install has it; checked by ``sha256``).
    """

    name: str
    path: str | None = None
    sha256: str | None = None
    embedded: str | None = None
    demo: str | None = None

    def __post_init__(self) -> None:
        given = sum(v is not None for v in (self.path, self.embedded, self.demo))
        if given != 1:
            raise SceneFileError("a scene's photo needs exactly one of path, embedded or demo")
        if self.demo not in (None, "synthetic", "shipped"):
            raise SceneFileError(
                f"unknown demo photo {self.demo!r}; the demos are 'synthetic' and 'shipped'"
            )
        if self.demo != "synthetic" and not (
            isinstance(self.sha256, str) and re.fullmatch(r"[0-9a-f]{64}", self.sha256)
        ):
            raise SceneFileError("a scene's photo needs its sha256 checksum (64 hex digits)")

    @classmethod
    def of_file(cls, path: str | Path, name: str | None = None, embed: bool = False) -> PhotoRef:
        """The photo file ``path`` by its absolute path and checksum, or embedded; the shipped
        photo (same bytes) as ``demo="shipped"``, so the scene opens on any install."""
        source = Path(path)
        content = source.read_bytes()
        digest = hashlib.sha256(content).hexdigest()
        label = name or source.name
        if embed:
            return cls(label, sha256=digest, embedded=base64.b64encode(content).decode("ascii"))
        if digest == _shipped_sha256():
            return cls(label, sha256=digest, demo="shipped")
        return cls(label, path=str(source.resolve()), sha256=digest)

    @classmethod
    def shipped(cls) -> PhotoRef:
        """The shipped photo, by name and checksum (no path).

        Raises:
            FileNotFoundError: it is not in this installation.
        """
        return cls(SHIPPED_PHOTO_NAME, sha256=_shipped_sha256(required=True), demo="shipped")

    @classmethod
    def of_bytes(cls, content: bytes, name: str) -> PhotoRef:
        """A photo known only by its bytes (an upload): embedded."""
        digest = hashlib.sha256(content).hexdigest()
        return cls(name, sha256=digest, embedded=base64.b64encode(content).decode("ascii"))

    def read(self, scene_folder: Path | None = None) -> bytes:
        """The photo file's bytes, checked against the checksum (not for the demo).

        Raises:
            SceneFileError: the file is missing, or its bytes do not match the checksum.
        """
        if self.demo == "synthetic":
            raise SceneFileError("the synthetic demo scene has no photo file")
        if self.demo == "shipped" or (
            self.path is not None
            and self.sha256 == _shipped_sha256()
            and not _resolved(self.path, scene_folder).is_file()
        ):  # an older scene names the shipped photo by a path on the machine that saved it
            content, where = _shipped_bytes(), "this installation's shipped photo"
        elif self.embedded is not None:
            try:
                content = base64.b64decode(self.embedded, validate=True)
            except ValueError:
                raise SceneFileError("the scene's embedded photo is not valid base64") from None
            where = "the embedded photo"
        else:
            assert self.path is not None
            source = _resolved(self.path, scene_folder)
            if not source.is_file():
                raise SceneFileError(
                    f"the scene's photo {source} is missing: put it back there, or save the "
                    "scene again with the photo embedded (--embed-photo)"
                )
            content, where = source.read_bytes(), f"the photo {source}"
        if hashlib.sha256(content).hexdigest() != self.sha256:
            raise SceneFileError(
                f"{where} does not match the scene's checksum: it changed since the scene was "
                "saved (boxes would land on other pixels); save the scene again from this photo"
            )
        return content

    def file_name(self, content: bytes) -> str:
        """A name with the photo's file suffix, for decoding ``content`` (the caption name of
        the shipped or an embedded photo may have none: the suffix is read from the bytes)."""
        if self.demo == "shipped":
            return SHIPPED_PHOTO[-1]
        named = Path(self.path).name if self.path is not None else self.name
        if Path(named).suffix.lower() in ALLOWED_SUFFIXES:
            return named
        if content[:4] == b"RIFF" and content[8:12] == b"WEBP":
            return f"{named}.webp"
        suffix = next((s for magic, s in _MAGIC_SUFFIXES if content.startswith(magic)), "")
        return named + suffix


def _resolved(path: str, scene_folder: Path | None) -> Path:
    source = Path(path)
    return scene_folder / source if not source.is_absolute() and scene_folder else source


def _shipped_bytes() -> bytes:
    try:
        return shipped_photo().read_bytes()
    except FileNotFoundError as error:
        raise SceneFileError(f"the scene shows the shipped photo, but {error}") from None


_SHIPPED_DIGEST: list[str] = []


def _shipped_sha256(required: bool = False) -> str | None:
    """The shipped photo's sha256 (None when this install lacks it, unless ``required``)."""
    if not _SHIPPED_DIGEST:
        try:
            _SHIPPED_DIGEST.append(hashlib.sha256(shipped_photo().read_bytes()).hexdigest())
        except FileNotFoundError:
            if required:
                raise
            return None
    return _SHIPPED_DIGEST[0]


@dataclass(frozen=True)
class OccluderEntry:
    """One occluder box ``(x0, y0, x1, y1)`` photo pixels, switched on or off."""

    box: Box
    enabled: bool = True


@dataclass(frozen=True)
class DisplaySettings:
    """How the scene is drawn (the *Samples* folder and the *Teaching* joint)."""

    colouring: str = "log"
    linear_top_cm: float = 10.0
    num_samples: int = 100
    num_displayed: int = 10
    show_samples: bool = True
    show_uncertainty_body: bool = True
    show_reprojection: bool = True
    show_fit: bool = True
    fit_opacity: float = 0.55
    selected_joint: str = "left_elbow"


@dataclass(frozen=True)
class SceneFile:
    """One explorer scene (see the module docstring).

    Attributes:
        photo: where the photo comes from.
        person_box: ``(x0, y0, x1, y1)`` photo pixels the person is looked for in, or None.
        occluders: the boxes hidden from the network, in list order.
        joint_factors: concentration factor per body joint that is not 1 (joint name ->
            factor in [0.1, 10]).
        all_joints_factor, shape_spread_factor: the global and shape-spread factors.
        evidence: condition on the 2D keypoints (else the network alone).
        person_mask: fit the person mask too.
        display: drawing settings.
        seed: the sample draw's seed.
        model: the checkpoint path (None: the shipped model).
        compare: the compare setting (:mod:`hkpd.explorer.compare`), or None.
        sex: the stated sex ("female", "male") or None (the photo decides).
        measurements: stated measurements, ``{name: [value, std]}`` in metres and kilograms
            (:data:`hkpd.stated_body.MEASUREMENT_NAMES`).
        turned_around: show the person's turned-around reading (*Turn around*; a file
            without this entry, written before it existed, reads as False).
    """

    photo: PhotoRef
    person_box: Box | None = None
    occluders: tuple[OccluderEntry, ...] = ()
    joint_factors: dict[str, float] = field(default_factory=dict)
    all_joints_factor: float = 1.0
    shape_spread_factor: float = 1.0
    evidence: bool = True
    person_mask: bool = False
    display: DisplaySettings = DisplaySettings()
    seed: int = 0
    model: str | None = None
    compare: str | None = None
    sex: str | None = None
    measurements: dict[str, list[float]] = field(default_factory=dict)
    turned_around: bool = False

    def __post_init__(self) -> None:
        _check_settings(self)

    def stated(self) -> StatedBody:
        """The stated sex and measurements, checked."""
        return StatedBody.of(
            self.sex, {name: (float(v), float(s)) for name, (v, s) in self.measurements.items()}
        )

    @property
    def active_boxes(self) -> list[Box]:
        """The enabled occluders' boxes, in list order."""
        return [entry.box for entry in self.occluders if entry.enabled]

    def joint_exponents(self) -> tuple[float, ...]:
        """``(23,)`` log10 of each body joint's factor, rounded as the app's state rounds."""
        return tuple(
            round(math.log10(self.joint_factors.get(name, 1.0)), 6) for name in BODY_JOINT_NAMES
        )

    def to_json(self) -> str:
        """The scene as JSON text (the format written to files)."""
        data = asdict(self)
        data["photo"] = {k: v for k, v in data["photo"].items() if v is not None}
        return json.dumps({"format": FORMAT, "version": VERSION, **data}, indent=1)

    def save(self, path: str | Path, force: bool = False) -> Path:
        """Write the scene to ``path``; an existing file is kept unless ``force``.

        Raises:
            SceneFileError: the file exists (and not ``force``) or its folder is missing.
        """
        target = Path(path)
        if not target.parent.is_dir():
            raise SceneFileError(f"folder {target.parent} does not exist: create it first")
        try:
            with target.open("w" if force else "x", encoding="utf-8") as file:
                file.write(self.to_json() + "\n")
        except FileExistsError:
            raise SceneFileError(
                f"{target} exists: choose another name, or pass --force to replace it"
            ) from None
        return target

    def with_photo(self, photo: PhotoRef) -> SceneFile:
        return replace(self, photo=photo)


def parse_scene(text: str, source: str = "the scene") -> SceneFile:
    """A scene from JSON text, or from an exported page that embeds one.

    Raises:
        SceneFileError: not JSON, not a scene file, another version, or bad settings.
    """
    stripped = text.lstrip()
    if stripped.startswith("<"):
        found = re.search(
            f'<script type="application/json" id="{PAGE_SCENE_ID}">(.*?)</script>', text, re.S
        )
        if found is None:
            raise SceneFileError(f"{source} is an HTML page without an hkpd scene in it")
        text = html.unescape(found.group(1))
    try:
        data = json.loads(text)
    except json.JSONDecodeError as error:
        raise SceneFileError(
            f"{source} is not valid JSON (line {error.lineno}, column {error.colno}: "
            f"{error.msg}); was it edited by hand?"
        ) from None
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise SceneFileError(f'{source} is not an hkpd explorer scene (no "format": "{FORMAT}")')
    if data.get("version") != VERSION:
        raise SceneFileError(
            f"{source} is a scene of version {data.get('version')!r}; this hkpd reads version "
            f"{VERSION}: save the scene again with this hkpd"
        )
    try:
        return _scene_from_dict(data)
    except (KeyError, TypeError, ValueError) as error:
        if isinstance(error, SceneFileError):
            raise SceneFileError(f"{source}: {error}") from None
        raise SceneFileError(f"{source} has a malformed entry: {error}") from None


def load_scene(path: str | Path) -> SceneFile:
    """Read and check the scene file (or exported page) ``path``.

    Raises:
        SceneFileError: missing or unreadable file, or as :func:`parse_scene`.
    """
    source = Path(path)
    try:
        text = source.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise SceneFileError(f"scene file {source} does not exist") from None
    except (OSError, UnicodeDecodeError) as error:
        raise SceneFileError(f"cannot read scene file {source}: {error}") from None
    return parse_scene(text, str(source))


def _scene_from_dict(data: dict[str, Any]) -> SceneFile:
    known = set(SceneFile.__dataclass_fields__)
    unknown = set(data) - known - {"format", "version"}
    if unknown:
        raise SceneFileError(f"unknown entries {sorted(unknown)}")
    values = {k: v for k, v in data.items() if k in known}
    values["photo"] = PhotoRef(**data["photo"])
    if values.get("person_box") is not None:
        values["person_box"] = _box(values["person_box"])
    values["occluders"] = tuple(
        OccluderEntry(_box(entry["box"]), bool(entry.get("enabled", True)))
        for entry in values.get("occluders", ())
    )
    values["display"] = DisplaySettings(**values.get("display", {}))
    values["joint_factors"] = {str(k): float(v) for k, v in values.get("joint_factors", {}).items()}
    values["measurements"] = {
        str(name): [float(v) for v in pair] for name, pair in values.get("measurements", {}).items()
    }
    return SceneFile(**values)


def _box(values: Any) -> Box:
    box = tuple(float(v) for v in values)
    if len(box) != 4 or not all(map(math.isfinite, box)) or box[2] <= box[0] or box[3] <= box[1]:
        raise SceneFileError(f"a box needs x0 y0 x1 y1 with x1 > x0 and y1 > y0, got {values}")
    return box  # type: ignore[return-value]


def _check_factor(name: str, factor: float) -> None:
    low, high = (10.0**e for e in CONCENTRATION_EXPONENT_RANGE)
    if not (isinstance(factor, float | int) and low - 1e-9 <= factor <= high + 1e-9):
        raise SceneFileError(f"{name}'s factor must be in {low:g}..{high:g}, got {factor}")


def _check_settings(scene: SceneFile) -> None:
    for name, factor in scene.joint_factors.items():
        if name not in BODY_JOINT_NAMES:
            raise SceneFileError(f"unknown joint {name!r}; joints: {', '.join(BODY_JOINT_NAMES)}")
        _check_factor(name, factor)
    _check_factor("all joints", scene.all_joints_factor)
    _check_factor("shape spread", scene.shape_spread_factor)
    display = scene.display
    if display.colouring not in COLOURINGS:
        raise SceneFileError(f"unknown colouring {display.colouring!r}; use {list(COLOURINGS)}")
    if not 2 <= display.num_samples <= MAX_SAMPLES:
        raise SceneFileError(f"samples must be in 2..{MAX_SAMPLES}, got {display.num_samples}")
    if not 0 <= display.num_displayed <= MAX_DISPLAYED_SAMPLES:
        raise SceneFileError(
            f"sample meshes must be in 0..{MAX_DISPLAYED_SAMPLES}, got {display.num_displayed}"
        )
    if display.selected_joint not in BODY_JOINT_NAMES:
        raise SceneFileError(f"unknown joint {display.selected_joint!r}")
    try:
        scene.stated()
    except (TypeError, ValueError) as error:
        raise SceneFileError(f"stated body: {error}") from None
    if not isinstance(scene.seed, int) or scene.seed < 0:
        raise SceneFileError(f"the seed must be a whole number >= 0, got {scene.seed!r}")
    if not isinstance(scene.turned_around, bool):
        raise SceneFileError(f"turned_around must be true or false, got {scene.turned_around!r}")
