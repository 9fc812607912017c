"""The league's own package (league.server.package): students install the code the server runs."""
from __future__ import annotations

import platform
import sysconfig

from fastapi import APIRouter, HTTPException, Request, status
from fastapi.responses import FileResponse

import league
from league.server.api.deps import SettingsDep
from league.server.api.schemas import PackageFileOut, PackageOut
from league.server.package import DISTRIBUTION, package_files

router = APIRouter(prefix="/package", tags=["package"])
EXTRAS = "onnx,client"  # what every student needs: check, submit, evaluate ONNX models (docs/STUDENT_GUIDE.md)


@router.get("", response_model=PackageOut)
def read_package(request: Request, settings: SettingsDep) -> PackageOut:
    """The wheel and sdist of the code this server runs, and the commands that install them (public)."""
    base = str(request.base_url).rstrip("/")
    files = []
    for file in _files(settings):
        url = f"{base}/api/package/{file.filename}"
        files.append(PackageFileOut(filename=file.filename, kind=file.kind, sha256=file.sha256,
                                    size=file.path.stat().st_size, url=url,
                                    install=f'pip install "{DISTRIBUTION}[{EXTRAS}] @ {url}"'))
    return PackageOut(version=league.__version__, python=platform.python_version(),
                      platform=sysconfig.get_platform(), files=files)


@router.get("/{filename}", response_class=FileResponse)
def read_package_file(filename: str, settings: SettingsDep) -> FileResponse:
    """One file of the package (public)."""
    for file in _files(settings):
        if file.filename == filename:
            return FileResponse(file.path, media_type="application/octet-stream", filename=file.filename,
                                headers={"Cache-Control": "no-cache"})
    raise HTTPException(status.HTTP_404_NOT_FOUND, f"no package file {filename!r}: GET /api/package lists them")


def _files(settings: SettingsDep):
    try:
        return package_files(settings.data_dir)
    except RuntimeError as error:  # a source tree whose sdist does not build
        raise HTTPException(status.HTTP_503_SERVICE_UNAVAILABLE, f"the package could not be built: {error}") from error
