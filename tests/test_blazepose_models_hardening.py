"""Damaged BlazePose models are refused on load with one message naming the file and how to
restore it (their sha256 is checked, once per process per file); intact ones still load."""

from __future__ import annotations

import hashlib
import importlib.util
import time
from pathlib import Path

import pytest

from hkpd.prediction.detection import blazepose, models
from hkpd.prediction.detection.models import (
    DETECTOR_MODEL,
    LANDMARK_MODEL,
    blazepose_model_path,
    read_blazepose_model,
)

needs_litert = pytest.mark.skipif(
    importlib.util.find_spec("ai_edge_litert") is None, reason="needs ai-edge-litert"
)


def _truncated(data: bytes) -> bytes:
    return data[: len(data) // 3]


def _text(data: bytes) -> bytes:
    return b"version https://git-lfs.github.com/spec/v1\noid sha256:0\nsize 6440512\n"


def _header_flipped(data: bytes) -> bytes:
    return bytes(byte ^ 0xFF for byte in data[:16]) + data[16:]


def _empty(data: bytes) -> bytes:
    return b""


def _middle_flipped(data: bytes) -> bytes:
    middle = len(data) // 2
    return (
        data[:middle] + bytes(b ^ 0x5A for b in data[middle : middle + 256]) + data[middle + 256 :]
    )


DAMAGES = [_truncated, _text, _header_flipped, _empty, _middle_flipped]


@pytest.fixture(autouse=True)
def fresh_verification_cache() -> None:
    models.forget_verified_models()


def _damaged_copy(tmp_path: Path, parts: tuple[str, str], damage) -> Path:
    copy = tmp_path / parts[1]
    copy.write_bytes(damage(blazepose_model_path(parts).read_bytes()))
    return copy


def _assert_clear(message: str, path: Path) -> None:
    assert "\n" not in message and str(path) in message, message
    assert "damaged" in message and "reinstall" in message, message


@pytest.mark.parametrize("parts", [DETECTOR_MODEL, LANDMARK_MODEL])
@pytest.mark.parametrize("damage", DAMAGES)
def test_a_damaged_model_file_is_refused_naming_it(tmp_path, monkeypatch, parts, damage) -> None:
    copy = _damaged_copy(tmp_path, parts, damage)
    monkeypatch.setattr(models, "shipped_file", lambda wanted, what, remedy: copy)
    with pytest.raises(ValueError) as caught:
        read_blazepose_model(parts)
    _assert_clear(str(caught.value), copy)


@needs_litert
@pytest.mark.parametrize("broken", [DETECTOR_MODEL, LANDMARK_MODEL])
@pytest.mark.parametrize("damage", DAMAGES)
def test_the_runner_refuses_a_damaged_model_before_the_interpreter_sees_it(
    tmp_path, monkeypatch, broken, damage
) -> None:
    copy = _damaged_copy(tmp_path, broken, damage)
    real = blazepose_model_path

    def path_of(parts: tuple[str, str]) -> Path:
        return copy if parts == broken else real(parts)

    monkeypatch.setattr(models, "blazepose_model_path", path_of)
    monkeypatch.setattr(blazepose, "blazepose_model_path", path_of, raising=False)
    with pytest.raises(ValueError) as caught:
        blazepose.BlazePose()
    _assert_clear(str(caught.value), copy)


def test_the_expected_digests_are_those_of_the_notice() -> None:
    notice = blazepose_model_path(DETECTOR_MODEL).with_name("NOTICE.md").read_text()
    assert set(models.MODEL_FILES) == {DETECTOR_MODEL[1], LANDMARK_MODEL[1]}
    for name, (size, digest) in models.MODEL_FILES.items():
        assert f"sha256 {digest}  {name}" in notice
        assert f"{size:,} bytes" in notice


def test_intact_models_are_hashed_once_per_process(monkeypatch) -> None:
    calls = []
    real = hashlib.sha256

    def counting(*arguments):
        calls.append(1)
        return real(*arguments)

    monkeypatch.setattr(models.hashlib, "sha256", counting)
    start = time.perf_counter()
    first = read_blazepose_model(LANDMARK_MODEL)
    once = time.perf_counter() - start
    again = read_blazepose_model(LANDMARK_MODEL)
    assert first == again == blazepose_model_path(LANDMARK_MODEL).read_bytes()
    assert len(calls) == 1
    assert once < 1.0  # 6.4 MB: a few ms unloaded
