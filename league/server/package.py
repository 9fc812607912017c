"""The league's own package, as the server hands it to students (GET /api/package): the code this
server runs, so that a student's `league evaluate` and `league check` are the server's own.

    wheel  rebuilt from the files this server runs: the installed distribution's files (its
           RECORD), or, for a server run from a source tree (`pip install -e .`, as the README and
           the Dockerfile install it), the package's files as its sdist lists them plus the
           compiled core this server imported. Tagged for this Python and platform (the core is
           compiled): it installs on machines like the server's, with no compiler.
    sdist  built from the source tree by setuptools' own hook (PEP 517), when the server runs from
           one: any platform with a C compiler (and Python >= 3.10) installs it, pip building the
           core; students whose machine is not like the server's take it. The hook runs in the
           server's own environment, which has the build's requirements (setuptools, Cython, numpy:
           the server extra installs them), so that it needs no package index: not pip's isolated
           build, which would fetch them at the first request, on a server that may have none.

Both are built once per source (their name says the version, their digest the content) into
DATA_DIR/package/<digest of the sources>/, on the first request; nothing here runs at start-up.
"""
from __future__ import annotations

import base64
import csv
import hashlib
import importlib.machinery
import importlib.metadata
import io
import os
import shutil
import subprocess
import sys
import sysconfig
import tarfile
import tempfile
import threading
import zipfile
from dataclasses import dataclass
from pathlib import Path

import league

DISTRIBUTION = "microracer-league"
PACKAGE_DIR = Path(league.__file__).resolve().parent
SOURCE_FILES = ("pyproject.toml", "setup.py", "setup.cfg", "MANIFEST.in", "README.md")  # beside the package
SKIPPED = ("__pycache__", ".pyc", ".c", ".so", ".pyd", ".egg-info")  # built, not sources
ZIP_TIME = (1980, 1, 1, 0, 0, 0)  # fixed: the same files give the same wheel, byte for byte


@dataclass(frozen=True)
class PackageFile:
    path: Path
    kind: str  # "wheel" or "sdist"
    sha256: str

    @property
    def filename(self) -> str:
        return self.path.name


_lock = threading.Lock()
_built: dict[Path, list[PackageFile]] = {}  # by data directory


def package_files(data_dir: Path) -> list[PackageFile]:
    """The wheel (and, from a source tree, the sdist) of the running code, built on first use."""
    with _lock:
        if data_dir not in _built:
            _built[data_dir] = _prepare(Path(data_dir) / "package")
        return _built[data_dir]


def _prepare(root: Path) -> list[PackageFile]:
    tree = source_tree()
    sources = _tree_sources(tree) if tree else _installed_sources()
    folder = root / _digest(sources)
    if not (folder / "done").exists():
        root.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(prefix="building-", dir=root))
        try:
            _build(tree, staging)
            (staging / "done").touch()
            if folder.exists():
                shutil.rmtree(folder)
            staging.rename(folder)
        finally:
            shutil.rmtree(staging, ignore_errors=True)
    return [PackageFile(path, "wheel" if path.suffix == ".whl" else "sdist", _sha256(path.read_bytes()))
            for path in sorted(folder.iterdir()) if path.name != "done"]


def _build(tree: Path | None, out: Path) -> None:
    if tree is None:
        write_wheel(out, *_installed_wheel_contents())
        return
    sdist = build_sdist(tree, out)
    write_wheel(out, *_tree_wheel_contents(sdist))


# --------------------------------------------------------------------------- where the code comes from


def source_tree() -> Path | None:
    """The source tree the running package is in (its pyproject names this distribution), if any."""
    root = PACKAGE_DIR.parent
    pyproject = root / "pyproject.toml"
    if pyproject.is_file() and f'name = "{DISTRIBUTION}"' in pyproject.read_text():
        return root
    return None


def _tree_sources(tree: Path) -> dict[str, bytes]:
    """What the sdist is built from: the project's files and the package's sources."""
    files = {name: (tree / name).read_bytes() for name in SOURCE_FILES if (tree / name).is_file()}
    for path in sorted(PACKAGE_DIR.rglob("*")):
        relative = path.relative_to(tree).as_posix()
        if path.is_file() and not any(part.endswith(SKIPPED) for part in relative.split("/")):
            files[relative] = path.read_bytes()
    return files


def _installed_sources() -> dict[str, bytes]:
    return _installed_wheel_contents()[0]


def _digest(files: dict[str, bytes]) -> str:
    digest = hashlib.sha256()
    for name in sorted(files):
        digest.update(name.encode() + b"\0" + _sha256(files[name]).encode())
    digest.update(f"{sys.implementation.cache_tag} {sysconfig.get_platform()}".encode())  # the compiled core's
    return digest.hexdigest()[:16]


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


# --------------------------------------------------------------------------- sdist


def build_sdist(tree: Path, out: Path) -> Path:
    """The sdist of the source tree, by setuptools' own PEP 517 hook, run on a copy of the sources
    (the build writes its egg-info and the generated C file where it runs)."""
    with tempfile.TemporaryDirectory(prefix="league-sdist-") as copy:
        for name, data in _tree_sources(tree).items():
            target = Path(copy) / name
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_bytes(data)
        code = "import sys; from setuptools import build_meta; print(build_meta.build_sdist(sys.argv[1]))"
        done = subprocess.run([sys.executable, "-c", code, str(out.resolve())], cwd=copy, capture_output=True,
                              text=True, timeout=600, env={**os.environ, "PYTHONDONTWRITEBYTECODE": "1"})
        if done.returncode != 0:
            raise RuntimeError(f"building the sdist failed: {done.stderr[-2000:]}")
    return out / done.stdout.strip().splitlines()[-1]


# --------------------------------------------------------------------------- wheel


def _tree_wheel_contents(sdist: Path) -> tuple[dict[str, bytes], dict[str, bytes], str]:
    """(package files, dist-info files, tag) of the wheel of a source tree: the package's files the
    sdist holds (not the generated C), the compiled core this server runs, the sdist's metadata."""
    files, info = {}, {}
    with tarfile.open(sdist) as archive:
        for member in archive.getmembers():
            name = member.name.split("/", 1)[1] if "/" in member.name else ""
            if not member.isfile():
                continue
            if name.startswith(f"{PACKAGE_DIR.name}/") and not name.endswith(".c"):
                files[name] = archive.extractfile(member).read()
            elif name == "PKG-INFO":
                info["METADATA"] = archive.extractfile(member).read()
            elif name.endswith((".egg-info/entry_points.txt", ".egg-info/top_level.txt")):
                info[name.rsplit("/", 1)[1]] = archive.extractfile(member).read()
    for core in PACKAGE_DIR.glob(f"*{importlib.machinery.EXTENSION_SUFFIXES[0]}"):
        files[f"{PACKAGE_DIR.name}/{core.name}"] = core.read_bytes()
    return files, info, _platform_tag()


def _installed_wheel_contents() -> tuple[dict[str, bytes], dict[str, bytes], str]:
    """(package files, dist-info files, tag) of the installed distribution, as its RECORD lists them."""
    dist = importlib.metadata.distribution(DISTRIBUTION)
    files, info, tag = {}, {}, None
    for entry in dist.files or []:
        name = entry.as_posix()
        if name.startswith("..") or "__pycache__" in name:
            continue  # console scripts (made again by the installer) and byte code
        if ".dist-info/" in name:
            base = name.rsplit("/", 1)[1]
            if base in ("METADATA", "entry_points.txt", "top_level.txt"):
                info[base] = entry.locate().read_bytes()
            elif base == "WHEEL":
                tag = next(line.split(":", 1)[1].strip() for line in entry.read_text().splitlines()
                           if line.startswith("Tag:"))
            continue
        files[name] = entry.locate().read_bytes()
    return files, info, tag or _platform_tag()


def _platform_tag() -> str:
    """This interpreter and platform, as bdist_wheel tags a compiled wheel (cp311-cp311-linux_x86_64)."""
    interpreter = f"cp{sys.version_info.major}{sys.version_info.minor}"
    platform = sysconfig.get_platform().replace("-", "_").replace(".", "_")
    return f"{interpreter}-{interpreter}-{platform}"


def write_wheel(out: Path, files: dict[str, bytes], info: dict[str, bytes], tag: str) -> Path:
    """A wheel (PEP 427) of `files` with the dist-info `info`, its WHEEL and its RECORD."""
    stem = f"{DISTRIBUTION.replace('-', '_')}-{_metadata_version(info)}"
    dist_info = f"{stem}.dist-info"
    contents = {**files, **{f"{dist_info}/{name}": data for name, data in info.items()}}
    contents[f"{dist_info}/WHEEL"] = (f"Wheel-Version: 1.0\nGenerator: league.server.package\n"
                                      f"Root-Is-Purelib: false\nTag: {tag}\n").encode()
    record = io.StringIO()
    writer = csv.writer(record, lineterminator="\n")
    for name, data in sorted(contents.items()):
        digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
        writer.writerow([name, f"sha256={digest}", len(data)])
    writer.writerow([f"{dist_info}/RECORD", "", ""])
    contents[f"{dist_info}/RECORD"] = record.getvalue().encode()
    path = out / f"{stem}-{tag}.whl"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as wheel:
        for name, data in sorted(contents.items(), key=lambda item: item[0].startswith(dist_info)):
            entry = zipfile.ZipInfo(name, ZIP_TIME)
            entry.external_attr = (0o755 if name.endswith((".so", ".pyd")) else 0o644) << 16
            entry.compress_type = zipfile.ZIP_DEFLATED
            wheel.writestr(entry, data)
    return path


def _metadata_version(info: dict[str, bytes]) -> str:
    for line in info["METADATA"].decode().splitlines():
        if line.startswith("Version:"):
            return line.split(":", 1)[1].strip()
    raise ValueError("the metadata has no Version")
