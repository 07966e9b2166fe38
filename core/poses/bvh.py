"""A small BVH (Biovision Hierarchy) reader: skeleton hierarchy and motion channels.

Only the parts of the format that motion-capture exports use are supported: one ``ROOT``, nested
``JOINT`` blocks, ``End Site`` blocks, ``OFFSET`` and ``CHANNELS`` lines (any order of the six
channel names, any subset per joint), and the ``MOTION`` section. Line endings may be LF or CRLF.

End sites become joints of the skeleton too (named ``"<parent>_end"``, no channels), so that the
tip of every chain has a position; :attr:`BvhSkeleton.is_end_site` tells them apart.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROTATION_CHANNELS = ("Xrotation", "Yrotation", "Zrotation")
POSITION_CHANNELS = ("Xposition", "Yposition", "Zposition")
_KNOWN_CHANNELS = ROTATION_CHANNELS + POSITION_CHANNELS


class BvhParseError(ValueError):
    """Raised when a BVH file cannot be understood; the message names the file and the problem."""


@dataclass(frozen=True)
class BvhSkeleton:
    """The hierarchy of a BVH file, joints in file order (parents before children).

    Attributes:
        names: joint names; end sites are named ``"<parent>_end"``.
        parents: parent index of each joint, -1 for the root.
        offsets: ``(J, 3)`` float64 offset of each joint from its parent, in the parent's frame,
            in the file's length unit (the root's offset is usually zero).
        channels: the channel names of each joint in file order (empty for end sites).
        is_end_site: ``(J,)`` bool.
    """

    names: tuple[str, ...]
    parents: tuple[int, ...]
    offsets: np.ndarray
    channels: tuple[tuple[str, ...], ...]
    is_end_site: np.ndarray

    @property
    def num_joints(self) -> int:
        """Number of joints, end sites included."""
        return len(self.names)

    @property
    def num_channels(self) -> int:
        """Number of numbers per motion frame."""
        return sum(len(c) for c in self.channels)

    def index(self, name: str) -> int:
        """Index of the joint called ``name``; raises KeyError listing the names if absent."""
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"no joint {name!r} in this skeleton; joints: {self.names}") from None


@dataclass(frozen=True)
class BvhMotion:
    """A parsed BVH file.

    Attributes:
        skeleton: the hierarchy.
        frames: ``(F, C)`` float64 channel values, angles in degrees, C = skeleton.num_channels.
        frame_time: seconds per frame as written in the file.
        name: the clip name (file stem) or ``""``.
    """

    skeleton: BvhSkeleton
    frames: np.ndarray
    frame_time: float
    name: str = ""

    @property
    def num_frames(self) -> int:
        return int(self.frames.shape[0])


def load_bvh(path: str | Path) -> BvhMotion:
    """Read a BVH file from disk (see :func:`parse_bvh`); the clip name is the file stem."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError as error:
        raise BvhParseError(f"{path}: cannot read file ({error})") from error
    try:
        return parse_bvh(text, name=path.stem)
    except BvhParseError as error:
        raise BvhParseError(f"{path}: {error}") from None


def parse_bvh(text: str, name: str = "") -> BvhMotion:
    """Parse the text of a BVH file.

    Args:
        text: the whole file (LF or CRLF line endings).
        name: clip name stored in the result.

    Returns:
        The skeleton and its motion frames.

    Raises:
        BvhParseError: on anything malformed (missing sections, bad numbers, wrong count of
            values per frame, unknown channel names).
    """
    text = text.replace("\r\n", "\n").replace("\r", "\n")
    head, separator, motion_text = text.partition("MOTION")
    if not separator:
        raise BvhParseError("no MOTION section")
    skeleton = _parse_hierarchy(head.split())
    frames, frame_time = _parse_motion(motion_text, skeleton.num_channels)
    return BvhMotion(skeleton=skeleton, frames=frames, frame_time=frame_time, name=name)


def _parse_hierarchy(tokens: list[str]) -> BvhSkeleton:
    """The skeleton of the ``HIERARCHY`` section, given as whitespace-separated tokens."""
    if not tokens or tokens[0] != "HIERARCHY":
        raise BvhParseError("file does not start with HIERARCHY")
    return _HierarchyReader(tokens).read()


class _HierarchyReader:
    """Reads the tokens after ``HIERARCHY`` one statement at a time, joints in file order."""

    def __init__(self, tokens: list[str]) -> None:
        self.tokens = tokens
        self.position = 1
        self.names: list[str] = []
        self.parents: list[int] = []
        self.offsets: list[list[float]] = []
        self.channels: list[tuple[str, ...]] = []
        self.end_site: list[bool] = []
        self.stack: list[int] = []  # joints whose '{' is open
        self.pending: int | None = None  # joint declared, waiting for its '{'

    def take(self) -> str:
        if self.position >= len(self.tokens):
            raise BvhParseError("hierarchy ends unexpectedly")
        token = self.tokens[self.position]
        self.position += 1
        return token

    def read(self) -> BvhSkeleton:
        statements = {
            "ROOT": self._joint,
            "JOINT": self._joint,
            "End": self._end_site,
            "{": self._open,
            "}": self._close,
            "OFFSET": self._offset,
            "CHANNELS": self._channels,
        }
        while self.position < len(self.tokens):
            token = self.take()
            if token not in statements:
                raise BvhParseError(f"unexpected token {token!r} in HIERARCHY")
            statements[token](token)
        if self.stack or self.pending is not None:
            raise BvhParseError("hierarchy has unclosed '{'")
        if not self.names:
            raise BvhParseError("hierarchy has no joints")
        return BvhSkeleton(
            names=tuple(self.names),
            parents=tuple(self.parents),
            offsets=np.asarray(self.offsets, dtype=np.float64),
            channels=tuple(self.channels),
            is_end_site=np.asarray(self.end_site, dtype=bool),
        )

    def _add(self, name: str, parent: int, is_end_site: bool) -> None:
        self.parents.append(parent)
        self.names.append(name)
        self.offsets.append([0.0, 0.0, 0.0])
        self.channels.append(())
        self.end_site.append(is_end_site)
        self.pending = len(self.names) - 1

    def _joint(self, token: str) -> None:
        if token == "ROOT" and (self.names or self.stack):
            raise BvhParseError("only one ROOT is supported")
        if token == "JOINT" and not self.stack:
            raise BvhParseError("JOINT outside of the ROOT block")
        joint_name = self.take()
        self._add(joint_name, self.stack[-1] if self.stack else -1, False)

    def _end_site(self, _token: str) -> None:
        if self.take() != "Site" or not self.stack:
            raise BvhParseError("malformed End Site")
        parent = self.stack[-1]
        self._add(f"{self.names[parent]}_end", parent, True)

    def _open(self, _token: str) -> None:
        if self.pending is None:
            raise BvhParseError("'{' without a joint")
        self.stack.append(self.pending)
        self.pending = None

    def _close(self, _token: str) -> None:
        if not self.stack:
            raise BvhParseError("unbalanced '}'")
        self.stack.pop()

    def _offset(self, _token: str) -> None:
        if not self.stack:
            raise BvhParseError("OFFSET outside a joint")
        joint = self.stack[-1]
        try:
            self.offsets[joint] = [float(self.take()) for _ in range(3)]
        except ValueError as error:
            raise BvhParseError(f"bad OFFSET of {self.names[joint]!r}: {error}") from None

    def _channels(self, _token: str) -> None:
        if not self.stack or self.end_site[self.stack[-1]]:
            raise BvhParseError("CHANNELS outside a joint")
        joint = self.stack[-1]
        try:
            count = int(self.take())
        except ValueError:
            raise BvhParseError(f"bad channel count for {self.names[joint]!r}") from None
        joint_channels = tuple(self.take() for _ in range(count))
        unknown = [c for c in joint_channels if c not in _KNOWN_CHANNELS]
        if unknown:
            raise BvhParseError(f"unknown channel(s) {unknown} in joint {self.names[joint]!r}")
        self.channels[joint] = joint_channels


def _parse_motion(text: str, num_channels: int) -> tuple[np.ndarray, float]:
    lines = text.split("\n")
    header: dict[str, str] = {}
    body_start = None
    for line_number, line in enumerate(lines):
        stripped = line.strip()
        if not stripped:
            continue
        key, colon, value = stripped.partition(":")
        if colon and key.strip() in ("Frames", "Frame Time"):
            header[key.strip()] = value.strip()
            if len(header) == 2:
                body_start = line_number + 1
                break
        else:
            raise BvhParseError(f"expected 'Frames:' and 'Frame Time:', found {stripped[:40]!r}")
    if body_start is None:
        raise BvhParseError("MOTION section lacks 'Frames:' or 'Frame Time:'")
    try:
        num_frames = int(header["Frames"])
        frame_time = float(header["Frame Time"])
    except ValueError as error:
        raise BvhParseError(f"bad MOTION header: {error}") from None
    try:
        values = np.array(" ".join(lines[body_start:]).split(), dtype=np.float64)
    except ValueError as error:
        raise BvhParseError(f"non-numeric motion data: {error}") from None
    if num_channels == 0 or values.size != num_frames * num_channels:
        raise BvhParseError(
            f"motion has {values.size} numbers but {num_frames} frames x {num_channels} "
            f"channels = {num_frames * num_channels} were declared"
        )
    if num_frames == 0:
        raise BvhParseError("motion has no frames")
    return values.reshape(num_frames, num_channels), frame_time
