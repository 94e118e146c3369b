"""Snakemake's between-workflow output cache (``--cache``; profile ``shipped``), kept read-only.

One cache entry is one unit: the files a cached job writes, each stored as ``<hash><suffix>``
under the job's provenance hash (an evaluation cell: ``<hash>_parquet.parquet``,
``<hash>_summary.json``, ``<hash>_traj.npz``; an oracle bound: ``<hash>.parquet``; V̂'s calibration:
``<hash>_report.json`` and its table as ``_csv.csv``, ``_md.md``, ``_html.html``). Two layers
(:func:`cache_layers`):

- the **committed** cache ``paths.output_cache`` (``output_cache/``) is only read: a run restores
  a cell from it when the cell's whole entry is there, and never stores into it;
- the **run's own** cache (``<paths.results>/output_cache``, or ``$SNAKEMAKE_OUTPUT_CACHE`` when
  set, which then is the only layer) is read too and takes the entries of cells computed anew,
  never onto an existing entry (:class:`LayeredOutputFileCache`).

``python -m madpinn publish`` copies a run's new entries into the committed cache (and its tables
and figures into ``paper_figures/``): the one command that changes them (issue 66 item 1).

Snakemake's own cache checks nothing: it restored a truncated entry as a finished cell (issue 50),
and with one member of an entry missing it linked the others in place, ran the job through those
links and moved the result onto the committed entry, leaving a symlink to itself (issue 66).
:func:`check_entries` reads every entry whole before any job and raises
:class:`CacheEntryError` (one line naming the entry and its fix) for the first that is
incomplete, a symlink, unreadable (Parquet: every column; JSON; NPZ: the CRC of every member) or,
in a git checkout, not its committed version; it writes nothing. Cost: ≈ 1 s for the protocol's
2 637 entries on one core.
"""

from __future__ import annotations

import json
import os
import shutil
import stat
import subprocess
import tempfile
import zipfile
from collections import defaultdict
from pathlib import Path
from typing import Iterable

HASH_LEN = 64
"""length of Snakemake's provenance hash (sha256, hex) at the start of every entry's file name"""
_HEX = frozenset("0123456789abcdef")


class CacheEntryError(RuntimeError):
    """An output-cache entry cannot be used (incomplete, a symlink, truncated, damaged or changed).
    ``fix`` (the line's fix, see :mod:`madpinn.commands.errors`) names the command that repairs it."""

    def __init__(self, message: str, fix: str | None = None):
        super().__init__(message)
        self.fix = fix


def _parquet(path: Path) -> None:
    import pyarrow.parquet as pq

    pq.read_table(path)


def _json(path: Path) -> None:
    json.loads(path.read_bytes())


def _text(path: Path) -> None:
    path.read_bytes().decode("utf-8")


def _npz(path: Path) -> None:
    with zipfile.ZipFile(path) as z:
        bad = z.testzip()
    if bad is not None:
        raise ValueError(f"member {bad} fails its CRC check")


READERS = {".parquet": _parquet, ".json": _json, ".npz": _npz, ".csv": _text, ".md": _text, ".html": _text}
"""Entry suffix (the cached output's own) -> a reader that raises when the entry is unreadable."""


KINDS = (("_parquet.parquet", "_summary.json", "_traj.npz"), (".parquet",),
         ("_report.json", "_csv.csv", "_md.md", "_html.html"))
"""The files of one entry of each cached rule (:func:`member_suffixes`): an evaluation cell (rule
``evaluate``), an oracle bound (``oracle``, ``oracle_pattern``), a V̂ calibration (``calibrate_vhat``:
≈ 4 min on one core, and the calibrated-level cells depend on it). The workflow checks at every start
with ``--cache`` that its cached rules still write these."""


def entry_hash(name: str) -> str | None:
    """The provenance hash a cache file name starts with, or None (README.md, a temporary directory)."""
    head = name[:HASH_LEN]
    return head if len(name) > HASH_LEN and len(head) == HASH_LEN and set(head) <= _HEX else None


def member_suffixes(rule) -> tuple[str, ...]:
    """The suffixes of the files an entry of Snakemake rule ``rule`` holds, as Snakemake names them
    (``AbstractOutputFileCache.get_outputfiles``): one output -> its extension; several named
    outputs -> ``_<name><extension>`` each."""
    outputs = list(rule.output._allitems())
    if rule.output[0].is_multiext:
        prefix = rule.output[0].multiext_prefix
        return tuple(str(out)[len(prefix):] for _, out in outputs)
    if len(outputs) == 1:
        return (Path(str(outputs[0][1])).suffix,)
    return tuple(f"_{name}{Path(str(out)).suffix}" for name, out in outputs)


def cache_layers(output_cache: str | None, results: str, env: str | None = None) -> tuple[Path | None, Path]:
    """(committed layer, the run's own layer), both absolute. ``$SNAKEMAKE_OUTPUT_CACHE`` (``env``),
    when set, is the one layer (read and written, never onto an existing entry); else the
    committed cache ``paths.output_cache`` is read only and ``<results>/output_cache`` is the run's."""
    if env:
        return None, Path(env).absolute()
    own = Path(results, "output_cache").absolute()
    committed = Path(output_cache).absolute() if output_cache else None
    return (None if committed == own else committed), own


def _shown(path: Path) -> str:
    """``path`` relative to the working directory when under it (never following a link: an
    entry may be a symlink to itself)."""
    path = Path(os.path.abspath(path))
    return os.path.relpath(path) if path.is_relative_to(os.path.abspath(os.getcwd())) else str(path)


def _git_state(directory: Path) -> tuple[set[str], dict[str, str]] | None:
    """(names git tracks in ``directory``, name -> status code of the tracked ones that differ from
    the index: M modified, T type changed, D deleted), or None outside a git work tree (or without
    git). Read with ``--no-optional-locks``: the check writes nothing, not even git's index."""
    def git(*args: str) -> str:
        return subprocess.run(["git", "--no-optional-locks", "-C", str(directory), *args], capture_output=True,
                              text=True, check=True, timeout=60).stdout

    try:
        prefix = git("rev-parse", "--show-prefix").strip()
        tracked = {n for n in git("ls-files", "-z", "--", ".").split("\0") if n and "/" not in n}
        changed = {}
        for item in git("status", "--porcelain=v1", "-z", "--untracked-files=no", "--", ".").split("\0"):
            if len(item) > 3 and item[:3].strip():
                name = item[3:].removeprefix(prefix)
                if "/" not in name:
                    changed[name] = item[1] if item[1] != " " else item[0]
        return tracked, changed
    except (OSError, subprocess.SubprocessError):
        return None


def _fix_for(directory: Path, names: Iterable[str], tracked: set[str], h: str) -> str:
    """Restore the named files from git when git tracks them all, else delete the whole entry
    (its job then runs again)."""
    names = sorted(names)
    if names and all(n in tracked for n in names):
        return f"restore the entry from git: git checkout -- {' '.join(_shown(directory / n) for n in names)}"
    return (f"delete the entry's files (rm {_shown(directory)}/{h}*; git does not track "
            f"{'them' if len(names) > 1 else 'it'}): its cell is then computed anew")


def check_entries(directory: str | Path, kinds: Iterable[Iterable[str]] = (), complete: bool = True,
                  git: bool = True) -> int:
    """Check every entry of the output cache ``directory`` as a whole; return how many files were
    read. Files whose name does not start with a provenance hash (its README, .gitignore) are
    skipped. Raises :class:`CacheEntryError` for the first entry with a member that is

    - a symlink (e.g. to itself, left by Snakemake's store onto an existing entry) or no regular file;
    - unreadable by the reader of its kind (truncated, damaged);
    - with ``git``, in a git work tree: tracked and not its committed version (modified, type changed);
    - with ``complete``: missing, the entry's other files being there (``kinds``: the suffix sets of
      the cached rules' entries, :func:`member_suffixes`; an entry of no known kind is not
      completed). The run's own layer, where another run may be storing an entry file by file,
      is checked with ``complete=False``.
    """
    directory = Path(directory)
    kinds = [tuple(k) for k in kinds]
    entries: dict[str, dict[str, Path]] = defaultdict(dict)
    for path in sorted(directory.iterdir()):
        h = entry_hash(path.name)
        if h is not None and (path.is_symlink() or not path.is_dir()):
            entries[h][path.name[HASH_LEN:]] = path
    state = _git_state(directory) if git and entries else None
    tracked, changed = state if state is not None else (set(), {})
    checked = 0
    for h, members in entries.items():
        for suffix, path in sorted(members.items()):
            shown = _shown(path)
            if path.is_symlink():
                target = os.readlink(path)
                what = ("a symlink to itself (left by a store onto an existing entry)"
                        if Path(directory, target).absolute() == path.absolute() else f"a symlink to {target}, not a file")
                raise CacheEntryError(f"output cache entry {shown} is {what}; a run would restore it or store onto it",
                                      _fix_for(directory, [path.name], tracked, h))
            if not path.is_file():
                raise CacheEntryError(f"output cache entry {shown} is not a regular file",
                                      _fix_for(directory, [path.name], tracked, h))
            reader = READERS.get(Path(suffix).suffix)
            try:
                reader and reader(path)
            except Exception as exc:  # noqa: BLE001 - any failure to read means the entry is unusable
                raise CacheEntryError(f"output cache entry {shown} is unreadable ({type(exc).__name__}: "
                                      f"{exc}); a run would restore it as a finished result",
                                      _fix_for(directory, [path.name], tracked, h)) from exc
            if changed.get(path.name) in ("M", "T"):
                raise CacheEntryError(f"output cache entry {shown} is not its committed version (git: modified); a run "
                                      "would restore it as the committed cell",
                                      _fix_for(directory, [path.name], tracked, h))
            checked += reader is not None
        if complete:
            kind = [k for k in kinds if set(members) <= set(k)]
            missing = sorted(set(kind[0]) - set(members)) if len(kind) == 1 else []
            if missing:
                names = [f"{h}{s}" for s in missing]
                raise CacheEntryError(
                    f"output cache entry {_shown(directory)}/{h[:12]}… is incomplete: its {', '.join(missing)} "
                    f"missing (it has {', '.join(sorted(members))}); a run would restore half a cell or store a "
                    "recomputed one onto it", _fix_for(directory, names, tracked, h))
    return checked


# --- the cache Snakemake uses: layered, append-only -------------------------------------------

def _snakemake_cache_base():
    from snakemake.caching.local import OutputFileCache

    return OutputFileCache


class _Layered:
    """Mixed into Snakemake's local ``OutputFileCache`` (see :func:`layered_cache_class`)."""

    def __init__(self, own: Path, committed: Path | None):
        from snakemake.caching.hash import ProvenanceHashMap

        self.cache_location = str(own)
        self.path = Path(own)
        self.layers = [p for p in (committed, Path(own)) if p is not None]
        self.provenance_hash_map = ProvenanceHashMap()
        self.file_permissions = stat.S_IRUSR | stat.S_IWUSR | stat.S_IRGRP | stat.S_IWGRP | stat.S_IROTH | stat.S_IWOTH
        self.dir_permissions = self.file_permissions | stat.S_IXUSR | stat.S_IXGRP | stat.S_IXOTH

    async def _entry(self, job) -> tuple[str, list[tuple[Path, str]]]:
        h = await self.provenance_hash_map.get_provenance_hash(job)
        return h, [(Path(out), ext) for out, ext in self.get_outputfiles(job)]

    def _whole_in(self, h: str, suffixes: list[str]) -> Path | None:
        """The first layer holding every file of entry ``h`` as a regular file (never a link)."""
        for layer in self.layers:
            files = [layer / f"{h}{s}" for s in suffixes]
            if all(f.is_file() and not f.is_symlink() for f in files):
                return layer
        return None

    async def exists(self, job) -> bool:
        h, outs = await self._entry(job)
        return self._whole_in(h, [ext for _, ext in outs]) is not None

    async def fetch(self, job) -> None:
        """Link the job's outputs to its whole entry; a cache miss (nothing linked) otherwise."""
        h, outs = await self._entry(job)
        layer = self._whole_in(h, [ext for _, ext in outs])
        if layer is None:
            self.raise_cache_miss_exception(job)
        for out, ext in outs:
            self.check_readable(layer / f"{h}{ext}")
        for out, ext in outs:
            if os.path.lexists(out):
                os.unlink(out)
            self.symlink(layer / f"{h}{ext}", out)

    async def store(self, job) -> None:
        """Store the job's outputs as a new entry of the run's own layer and link them back; when
        any layer already has a file of this entry, store nothing: the outputs stay in results/."""
        from snakemake.exceptions import WorkflowError
        from snakemake.logging import logger

        h, outs = await self._entry(job)
        taken = [layer / f"{h}{ext}" for layer in self.layers for _, ext in outs if os.path.lexists(layer / f"{h}{ext}")]
        if taken:
            logger.warning(f"madpinn: {outs[0][0]} was computed anew and stays in results/: its cache entry "
                           f"{_shown(taken[0])} exists, and nothing is stored onto an existing entry")
            return
        for out, _ in outs:
            if os.path.islink(out) or not os.path.isfile(out):
                raise WorkflowError(f"cannot store {out} in the output cache: not a file the job wrote")
        self.path.mkdir(parents=True, exist_ok=True)
        if not os.access(self.path, os.W_OK):
            raise WorkflowError(f"cannot write the output cache {self.path}")
        with tempfile.TemporaryDirectory(dir=self.path) as tmpdir:
            staged = []
            for out, ext in outs:
                tmp = Path(tmpdir) / f"{h}{ext}"
                shutil.copyfile(out, tmp)
                self.set_permissions(tmp)
                staged.append((out, tmp, self.path / f"{h}{ext}"))
            linked = []
            try:
                for _, tmp, entry in staged:
                    os.link(tmp, entry)       # never onto an existing file (another run's entry)
                    linked.append(entry)
            except FileExistsError:
                for entry in linked:          # ours alone (the same inode as our staged copy)
                    os.unlink(entry)
                logger.warning(f"madpinn: {outs[0][0]} stays in results/: another run stored its cache entry "
                               f"{h[:12]}… meanwhile")
                return
            for out, _, entry in staged:
                os.unlink(out)
                logger.info(f"Moving output file {out} to cache.")
                self.symlink(entry, out, utime=False)


def layered_cache_class(own: Path, committed: Path | None):
    """A factory for Snakemake's ``LocalOutputFileCache`` (called without arguments when the DAG is
    prepared) that builds the two-layer, append-only cache of ``own`` over ``committed``."""
    base = _snakemake_cache_base()
    cls = type("LayeredOutputFileCache", (_Layered, base), {})
    return lambda: cls(own, committed)


def install(own: Path, committed: Path | None) -> None:
    """Make Snakemake (9.27.1, pinned) use the layered cache: the workflow module builds its local
    cache from the name ``LocalOutputFileCache`` after the Snakefile is read."""
    import snakemake.workflow as smk_workflow

    smk_workflow.LocalOutputFileCache = layered_cache_class(own, committed)


# --- publish: the one command that adds entries to the committed cache --------------------------

def whole_entries(directory: Path, kinds: Iterable[Iterable[str]]) -> dict[str, list[Path]]:
    """hash -> files of every entry of ``directory`` that is whole (all files of one kind, regular)."""
    kinds = [tuple(k) for k in kinds]
    members: dict[str, dict[str, Path]] = defaultdict(dict)
    if directory.is_dir():
        for path in directory.iterdir():
            h = entry_hash(path.name)
            if h is not None:
                members[h][path.name[HASH_LEN:]] = path
    whole = {}
    for h, files in members.items():
        if any(set(files) == set(k) for k in kinds) and all(p.is_file() and not p.is_symlink() for p in files.values()):
            whole[h] = sorted(files.values())
    return whole


def add_entries(source: Path, dest: Path, kinds: Iterable[Iterable[str]]) -> tuple[list[str], list[str]]:
    """Copy every whole entry of ``source`` whose hash has no file in ``dest`` into ``dest`` (each
    file checked by its reader first, written by a hard link of a staged copy: never onto an
    existing file). Returns (hashes added, hashes skipped because ``dest`` has them)."""
    kinds = [tuple(k) for k in kinds]
    dest.mkdir(parents=True, exist_ok=True)
    have = {entry_hash(p.name) for p in dest.iterdir()} - {None}
    added, skipped = [], []
    for h, files in sorted(whole_entries(source, kinds).items()):
        if h in have:
            skipped.append(h)
            continue
        for f in files:
            reader = READERS.get(f.suffix)
            try:
                reader and reader(f)
            except Exception as exc:  # noqa: BLE001
                raise CacheEntryError(f"output cache entry {_shown(f)} is unreadable ({type(exc).__name__}: {exc}); "
                                      "nothing of it was published", f"delete the entry's files (rm {_shown(source)}/{h}*): "
                                      "its cell is then computed anew") from exc
        with tempfile.TemporaryDirectory(dir=dest) as tmpdir:
            for f in files:
                tmp = Path(tmpdir) / f.name
                shutil.copyfile(f, tmp)
                os.link(tmp, dest / f.name)
        added.append(h)
    return added, skipped
