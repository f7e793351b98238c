"""How the project touches disk: atomic files and folders, content hashes, and the package
versions recorded beside every written dataset or run.

One home for these so that every writer (formats, datasets, run folders) gets the same crash
safety: a file or folder appears under its final name only when complete.
"""
from __future__ import annotations

import hashlib
import json
import os
import platform
import re
import secrets
import shutil
import socket
import threading
import time
from contextlib import contextmanager
from functools import lru_cache
from importlib import metadata
from pathlib import Path
from typing import Iterable, Iterator

HASH_FILE = "files.sha256"


@contextmanager
def atomic_path(path: Path, *, suffix: str = "", hidden: bool = True) -> Iterator[Path]:
    """The one atomic-write helper: yield a temporary sibling of ``path``,
    ``[.]NAME.tmp-<run id>[suffix]``, for the caller to write; on success it is renamed over
    ``path``, on any error removed, so ``path`` is never half-written.

    For writers that want a file name (``torch.save``, ``np.savez``, ``fig.savefig``); text and
    bytes go through :func:`write_atomic`. ``suffix``: for writers that append their own when it
    is missing (``np.savez``: ``".npz"``). ``hidden=False`` for ``torch.save``, which names the
    archive inside the file after the file name up to its last dot: ``NAME.tmp-<id>`` keeps it
    ``NAME``, so the bytes do not depend on the temporary's name."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f"{'.' if hidden else ''}{path.name}.tmp-{run_id()}{suffix}")
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_atomic(path: Path, data: str | bytes) -> None:
    """Write via a temporary sibling and rename (no half-written file on failure)."""
    with atomic_path(path) as tmp:
        if isinstance(data, bytes):
            tmp.write_bytes(data)
        else:
            tmp.write_text(data)


def hash_tree(folder: Path) -> dict[str, str]:
    """sha256 of every file under folder (except the hash file), keyed by posix relative path."""
    out = {}
    for path in sorted(folder.rglob("*")):
        if path.name in BOOKKEEPING:
            continue
        if path.is_symlink():  # never followed: a link is recorded as what it is, so verify flags it
            out[path.relative_to(folder).as_posix()] = f"symlink:{os.readlink(path)}"
        elif path.is_file():
            out[path.relative_to(folder).as_posix()] = hashlib.sha256(path.read_bytes()).hexdigest()
    return out


def write_hashes(folder: Path) -> str:
    """Write files.sha256 (sha256sum format) and return the sequence content hash."""
    hashes = hash_tree(folder)
    lines = "".join(f"{digest}  {rel}\n" for rel, digest in hashes.items())
    (folder / HASH_FILE).write_text(lines)
    return hashlib.sha256(lines.encode()).hexdigest()


def verify_hashes(folder: Path) -> list[str]:
    """Relative paths that are missing, extra or whose bytes changed; empty when intact."""
    listed_file = folder / HASH_FILE
    if not listed_file.is_file():
        return [HASH_FILE]
    listed = {}
    try:
        lines = listed_file.read_text().splitlines()
    except UnicodeDecodeError:
        return [HASH_FILE]
    for number, line in enumerate(lines, start=1):
        digest, sep, rel = line.partition("  ")
        if not sep or len(digest) != 64 or any(c not in "0123456789abcdef" for c in digest) or not rel:
            return [f"{HASH_FILE} (line {number} is not '<sha256>  <path>')"]
        listed[rel] = digest
    actual = hash_tree(folder)
    return sorted(rel for rel in set(listed) | set(actual) if listed.get(rel) != actual.get(rel))


# --------------------------------------------------------------------------------------------
# The safe-output rule (docs/RELIABILITY.md): every command's output folder is created new, or is
# one evids wrote (it holds MARKER_FILE, or is a recognised evids dataset/sequence/run) and the
# command was asked to replace it; never the input, an ancestor or descendant of it, or ".".
# --------------------------------------------------------------------------------------------

MARKER_FILE = ".evids-output.json"
LOCK_FILE = ".evids.lock"
#: the cross-host lease beside the per-host lock (see :class:`DatasetLock`)
LEASE_FILE = ".evids.lease"
#: files that are bookkeeping, not content (never hashed, never counted as "user files")
BOOKKEEPING = (HASH_FILE, MARKER_FILE, LOCK_FILE, LEASE_FILE)
_NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._+-]{0,127}$")


def _host_tag() -> str:
    return hashlib.sha256(socket.gethostname().encode()).hexdigest()[:8]


#: id of this process's run: pid, host hash and a random token (temp folders carry it)
RUN_ID = f"r{os.getpid()}-{_host_tag()}-{secrets.token_hex(3)}"
_TEMP_RE = re.compile(r"^\.(?:tmp|old|native)-(?P<name>.+)-r(?P<pid>\d+)-(?P<host>[0-9a-f]{8})-(?P<token>[0-9a-f]{6})$")


def run_id() -> str:
    """This process's run id (recomputed after fork so a child never reuses its parent's)."""
    global RUN_ID
    if not RUN_ID.startswith(f"r{os.getpid()}-"):
        RUN_ID = f"r{os.getpid()}-{_host_tag()}-{secrets.token_hex(3)}"
    return RUN_ID


def check_plain_name(name: str, field: str) -> str:
    """A name used as one path component: letters, digits, ``._+-``, not starting with a dot or
    dash, at most 128 characters (no separators, no ``..``, not absolute). Returns it."""
    from scenes.errors import UserInputError, short_repr

    if not isinstance(name, str) or not _NAME_RE.match(name) or name in (".", ".."):
        raise UserInputError(f"{field}: must be a plain name (letters, digits, '._+-', not starting with '.' "
                             f"or '-', at most 128 characters), got {short_repr(name)}")
    return name


def inside(child: Path, root: Path) -> Path:
    """``child`` resolved, refused unless it lies inside ``root`` (resolved): for paths built from
    names taken from inputs."""
    from scenes.errors import UserInputError

    c, r = Path(child).resolve(), Path(root).resolve()
    if c != r and r not in c.parents:
        raise UserInputError(f"{child}: resolves to {c}, outside the output folder {r}")
    return c


def is_evids_output(folder: Path) -> bool:
    """True if ``folder`` was written by evids: it holds the marker, or it is a native dataset,
    native sequence, TRIDENT set or run folder in the layouts this project writes."""
    folder = Path(folder)
    if any((folder / name).is_file() for name in (MARKER_FILE, LOCK_FILE, LEASE_FILE)):
        return True
    manifest = folder / "manifest.json"
    if manifest.is_file():
        try:
            fmt = json.loads(manifest.read_text()).get("format")
        except (ValueError, OSError, AttributeError):
            return False
        return fmt in ("evids-native-dataset", "trident") and (folder / "manifest.json").is_file()
    if (folder / "config.yaml").is_file() and (folder / "run.json").is_file():
        return True  # an experiment run folder
    if (folder / "config.json").is_file() and (folder / "data.json").is_file():
        return True  # a detection run folder
    return (folder / "meta.json").is_file() and (folder / HASH_FILE).is_file()


def _is_empty_dir(folder: Path) -> bool:
    """No entries besides evids' own bookkeeping (a lock or marker left by a killed run)."""
    return folder.is_dir() and not folder.is_symlink() and all(c.name in BOOKKEEPING[1:]
                                                               for c in folder.iterdir())


def _overlaps(a: Path, b: Path) -> bool:
    return a == b or a in b.parents or b in a.parents


def check_output(out: Path, *, inputs: Iterable[Path] = (), overwrite: bool = False, flag: str = "--out",
                 allow_resume: bool = False) -> None:
    """The safe-output rule, checked before any work starts; raises UserInputError saying why.

    ``out`` may be missing or an empty folder; otherwise it must be an evids output and either
    ``overwrite`` is set or ``allow_resume`` (a run/dataset the command continues). It may never be
    the current folder, a filesystem root or the home folder, nor overlap any of ``inputs``."""
    from scenes.errors import UserInputError

    raw = Path(out)
    resolved = raw.resolve()
    cwd = Path.cwd().resolve()
    if resolved == cwd or resolved in cwd.parents:
        raise UserInputError(f"{flag} {str(raw)!r} is the current folder or one of its parents; give a new sub-folder")
    if resolved == Path(resolved.anchor) or resolved == Path.home().resolve():
        raise UserInputError(f"{flag} {str(raw)!r} is a root or home folder; give a new sub-folder")
    check_no_overlap(raw, inputs, flag)
    if raw.is_symlink():
        raise UserInputError(f"{flag} {str(raw)!r} is a symbolic link; give a real folder")
    if not raw.exists() or _is_empty_dir(raw):
        return
    if not raw.is_dir():
        raise UserInputError(f"{flag} {str(raw)!r} exists and is not a folder")
    if not is_evids_output(raw):
        raise UserInputError(f"{flag} {str(raw)!r} is not empty and was not written by evids; nothing was changed "
                             "(choose a new folder)")
    if not (overwrite or allow_resume):
        raise UserInputError(f"{flag} {str(raw)!r} already holds evids output; use --overwrite to replace it")


def check_no_overlap(out: Path, inputs: Iterable[Path], flag: str = "--out") -> None:
    """Refuse an output folder that is, contains or lies inside any input (UserInputError)."""
    from scenes.errors import UserInputError

    resolved = Path(out).resolve()
    for inp in inputs:
        inp_r = Path(inp).resolve()
        if _overlaps(resolved, inp_r):
            rel = "is" if resolved == inp_r else ("contains" if resolved in inp_r.parents else "is inside")
            raise UserInputError(f"{flag} {str(out)!r} {rel} the input {str(inp)!r}; write somewhere else")


def pid_running(pid: int) -> bool:
    """``pid`` is a running process here (not gone, not a zombie waiting to be reaped)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rpartition(")")[2].split()[0] != "Z"
    except OSError:  # no /proc (not Linux), or gone meanwhile
        return os.path.exists(f"/proc/{pid}") or not os.path.isdir("/proc")


def clean_dead_temps(parent: Path, name: str | None = None) -> list[Path]:
    """Remove hidden temp/old folders under ``parent`` (for ``name`` only, if given) whose owning
    run is dead (same host, pid gone); a live run's temporaries are never touched. Returns them."""
    removed: list[Path] = []
    parent = Path(parent)
    if not parent.is_dir():
        return removed
    for child in parent.iterdir():
        m = _TEMP_RE.match(child.name)
        if not m or (name is not None and m.group("name") != name):
            continue
        if m.group("host") != _host_tag() or pid_running(int(m.group("pid"))):
            continue
        _remove(child)
        removed.append(child)
    return removed


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        path.unlink(missing_ok=True)


def temp_sibling(final: Path, kind: str = "tmp") -> Path:
    """Hidden sibling of ``final`` carrying this run's id: ``.tmp-<name>-<run id>``."""
    return Path(final).parent / f".{kind}-{Path(final).name}-{run_id()}"


def write_marker(folder: Path, kind: str) -> None:
    """Mark ``folder`` as written by evids (``kind``: what wrote it); deterministic content."""
    (Path(folder) / MARKER_FILE).write_text(json.dumps({"written_by": "evids", "kind": kind}, sort_keys=True) + "\n")


@contextmanager
def atomic_folder(final: Path, *, overwrite: bool = False, kind: str | None = None) -> Iterator[Path]:
    """Yield a temporary sibling folder (named with this run's id); on success mark it (if ``kind``
    is given: a command's published output, not a folder inside a public-format layout) and rename
    it to ``final``; on any error remove it and leave ``final`` untouched.

    An existing ``final`` is replaced only if ``overwrite`` and it is empty or an evids output
    (:func:`is_evids_output`); otherwise FileExistsError (before any work, and again at the rename).
    Dead runs' temporaries of the same ``final`` are removed first."""
    final = Path(final)
    _check_replaceable(final, overwrite)
    final.parent.mkdir(parents=True, exist_ok=True)
    clean_dead_temps(final.parent, final.name)
    tmp = temp_sibling(final)
    if tmp.exists():
        shutil.rmtree(tmp)
    tmp.mkdir()
    try:
        yield tmp
        if kind is not None:
            write_marker(tmp, kind)
        _check_replaceable(final, overwrite)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    if final.exists() or final.is_symlink():
        old = temp_sibling(final, "old")
        final.rename(old)
        tmp.rename(final)
        shutil.rmtree(old, ignore_errors=True)
    else:
        tmp.rename(final)


def _check_replaceable(final: Path, overwrite: bool) -> None:
    if not (final.exists() or final.is_symlink()):
        return
    if final.is_symlink() or not final.is_dir():
        raise FileExistsError(f"{final} exists and is not a folder evids wrote; not replaced")
    if _is_empty_dir(final):
        return
    if not is_evids_output(final):
        raise FileExistsError(f"{final} holds files evids did not write; not replaced")
    if not overwrite:
        raise FileExistsError(f"{final} already exists (ask for --overwrite to replace it)")


def remove_output(folder: Path) -> None:
    """Delete ``folder`` only if it is an evids output (or absent/empty); otherwise FileExistsError."""
    folder = Path(folder)
    if not (folder.exists() or folder.is_symlink()):
        return
    _check_replaceable(folder, overwrite=True)
    shutil.rmtree(folder)


def copy_tree_no_symlinks(src: Path, dst: Path, *, skip: Iterable[str] = (), hard_link: bool = False) -> None:
    """Copy regular files and folders of ``src`` into ``dst``; a symbolic link anywhere is refused
    (never followed), so no byte from outside ``src`` can enter the copy. ``hard_link``: each file is
    a hard link to its source where the file system allows one (a copy elsewhere): safe because evids
    never modifies a file in place (every write replaces it, ``write_atomic``)."""
    from scenes.errors import UserInputError

    src, dst = Path(src), Path(dst)
    skip = set(skip)
    for root, dirs, files in os.walk(src, followlinks=False):
        rel = Path(root).relative_to(src)
        for name in dirs + files:
            path = Path(root) / name
            if path.is_symlink():
                raise UserInputError(f"{path}: is a symbolic link; evids does not follow links in an input folder")
        (dst / rel).mkdir(parents=True, exist_ok=True)
        for name in files:
            if (rel / name).as_posix() in skip or name in BOOKKEEPING[1:]:
                continue
            if hard_link:
                try:
                    os.link(Path(root) / name, dst / rel / name, follow_symlinks=False)
                    continue
                except OSError:   # another device, or a file system without hard links: copy
                    pass
            shutil.copy2(Path(root) / name, dst / rel / name, follow_symlinks=False)


# --------------------------------------------------------------------------------------------
# Dataset lock: one writer per dataset folder
# --------------------------------------------------------------------------------------------

#: seconds a dataset lease lasts without renewal; the holder renews it every third of that
LEASE_S = 60.0


class DatasetLock:
    """Exclusive lock on a dataset folder, on one host and across hosts that share the folder.

    - Across hosts: ``DIR/.evids.lease`` (owner host, pid, run id, ``expires_unix``), created
      exclusively (``O_EXCL``: atomic on local disks and on NFSv3+), renewed every ``lease_s / 3`` by
      a daemon thread while the run lives and removed on release. Another host's lease that has not
      expired refuses the run (naming host, pid and expiry); an expired one (its host died, hung or
      lost the folder), or one of this host whose pid is dead, is taken over and reported in
      ``stale``. Hosts' clocks must agree to well within ``lease_s``.
    - Per host: ``DIR/.evids.lock`` (pid, host, run id) kept with an OS-level ``flock`` for the
      run's lifetime (released when the process dies, even by SIGKILL); a lock file left by a dead
      run is reported in ``stale`` and taken over.
    """

    def __init__(self, folder: Path, purpose: str = "write", *, required: bool = True, lease_s: float = LEASE_S):
        """``required=False`` (readers such as export): a folder where no lock file can be created
        (read-only media) is used unlocked, since no writer can change it either."""
        if not lease_s > 0:
            raise ValueError(f"lease_s must be > 0, got {lease_s}")
        self.required = required
        self.folder = Path(folder)
        self.path = self.folder / LOCK_FILE
        self.lease_path = self.folder / LEASE_FILE
        self.purpose = purpose
        self.lease_s = float(lease_s)
        self.stale: dict | None = None
        #: set when another run took the lease from this one (this run stalled past its expiry)
        self.lost = False
        self._fd: int | None = None
        self._lease: dict | None = None
        self._stop: threading.Event | None = None
        self._renewer: threading.Thread | None = None

    def acquire(self) -> "DatasetLock":
        import fcntl

        from scenes.errors import UserInputError

        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            self._take_lease()
        except OSError:
            if self.required:
                raise
            return self
        try:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = _read_lock(fd)
                os.close(fd)
                raise UserInputError(
                    f"{self.folder} is locked by another evids run (pid {holder.get('pid', '?')} on host "
                    f"{holder.get('host', '?')}, {holder.get('purpose', 'write')}); wait for it to finish") from None
        except BaseException:
            self._drop_lease()
            raise
        previous = _read_lock(fd)
        if previous and self.stale is None:
            self.stale = previous
        info = {"pid": os.getpid(), "host": socket.gethostname(), "run_id": run_id(), "purpose": self.purpose}
        os.ftruncate(fd, 0)
        os.pwrite(fd, (json.dumps(info, sort_keys=True) + "\n").encode(), 0)
        os.fsync(fd)
        self._fd = fd
        self._stop = threading.Event()
        self._renewer = threading.Thread(target=self._renew, args=(self._stop,), name="evids-lease-renewal",
                                         daemon=True)
        self._renewer.start()
        return self

    # -- the lease -----------------------------------------------------------------------------

    def _record(self) -> dict:
        return {"host": socket.gethostname(), "pid": os.getpid(), "run_id": run_id(), "purpose": self.purpose,
                "lease_s": self.lease_s, "expires_unix": round(time.time() + self.lease_s, 3)}

    def _expired(self, holder: dict) -> bool:
        """True when ``holder``'s lease may be taken over: past its expiry, or its pid is dead on this host."""
        expires = holder.get("expires_unix")
        if not isinstance(expires, (int, float)):  # unreadable (a renewal being written): judge by its age
            try:
                expires = self.lease_path.stat().st_mtime + self.lease_s
            except FileNotFoundError:
                return True
        if time.time() > float(expires):
            return True
        pid = holder.get("pid")
        return holder.get("host") == socket.gethostname() and not (isinstance(pid, int) and pid > 0
                                                                    and pid_running(pid))

    def _take_lease(self) -> None:
        from scenes.errors import UserInputError

        for _ in range(5):
            try:
                fd = os.open(self.lease_path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
            except FileExistsError:
                holder = _read_json(self.lease_path)
                if holder == {}:  # caught half-way through a renewal: read it again
                    time.sleep(0.05)
                    holder = _read_json(self.lease_path)
                if holder is None:  # released in between
                    continue
                if not self._expired(holder):
                    left = float(holder.get("expires_unix", time.time())) - time.time()
                    raise UserInputError(
                        f"{self.folder} is locked by another evids run (pid {holder.get('pid', '?')} on host "
                        f"{holder.get('host', '?')}, {holder.get('purpose', 'write')}; its lease "
                        f"{self.lease_path.name} expires in {max(0.0, left):.0f} s unless renewed); wait for it to "
                        "finish, or for the lease to expire if that host is down") from None
                # take the dead lease over: move it aside (atomic, so one taker wins), check it is the one
                # judged dead (not a fresh lease another taker created meanwhile: that one is put back)
                aside = self.folder / f"{LEASE_FILE}.expired-{run_id()}"
                try:
                    os.rename(self.lease_path, aside)
                except FileNotFoundError:
                    continue
                moved = _read_json(aside)
                if moved != holder:
                    try:
                        os.link(aside, self.lease_path)
                    except FileExistsError:
                        pass
                    aside.unlink(missing_ok=True)
                    continue
                aside.unlink(missing_ok=True)
                self.stale = {**holder, "note": "expired lease taken over"}
                continue
            record = self._record()
            with os.fdopen(fd, "w") as f:
                f.write(json.dumps(record, sort_keys=True) + "\n")
                f.flush()
                os.fsync(f.fileno())
            self._lease = record
            return
        raise UserInputError(f"{self.folder}: another run is taking the dataset lease at the same time; try again")

    def _renew(self, stop: threading.Event) -> None:
        """Push the lease's expiry forward every third of the lease while the run holds it."""
        while not stop.wait(self.lease_s / 3):
            self.renew()

    def renew(self) -> bool:
        """Extend the lease now; False (and ``lost`` set) when another run has taken it over."""
        if self._lease is None:
            return False
        current = _read_json(self.lease_path)
        if current is not None and current.get("run_id") != self._lease["run_id"] or not self.lease_path.exists():
            self.lost = True
            return False
        self._lease = {**self._lease, "expires_unix": round(time.time() + self.lease_s, 3)}
        try:
            with open(self.lease_path, "r+") as f:  # in place: a reader that catches it half-written goes by mtime
                f.truncate(0)
                f.write(json.dumps(self._lease, sort_keys=True) + "\n")
        except FileNotFoundError:
            self.lost = True
            return False
        return True

    def _drop_lease(self) -> None:
        if self._stop is not None:
            self._stop.set()
            self._stop = None
        if self._renewer is not None:
            # a renewal caught between its truncate and its write would leave an empty lease that the
            # next run reads as fresh (and, with the process gone, nobody removes): let it finish first
            if self._renewer is not threading.current_thread():
                self._renewer.join(timeout=30.0)
            self._renewer = None
        if self._lease is not None:
            current = _read_json(self.lease_path)
            if current is None or current.get("run_id") == self._lease["run_id"]:
                self.lease_path.unlink(missing_ok=True)
            self._lease = None

    def release(self) -> None:
        import fcntl

        self._drop_lease()
        if self._fd is None:
            return
        try:
            os.ftruncate(self._fd, 0)
            self.path.unlink(missing_ok=True)
        finally:
            fcntl.flock(self._fd, fcntl.LOCK_UN)
            os.close(self._fd)
            self._fd = None

    def __enter__(self) -> "DatasetLock":
        return self.acquire()

    def __exit__(self, *exc) -> None:
        self.release()


def _read_json(path: Path) -> dict | None:
    """A lease file's record; None when it is gone, {} when it cannot be read (being written)."""
    try:
        text = path.read_text()
    except FileNotFoundError:
        return None
    try:
        value = json.loads(text)
    except ValueError:
        return {}
    return value if isinstance(value, dict) else {}


def _read_lock(fd: int) -> dict:
    try:
        text = os.pread(fd, 4096, 0).decode("utf-8", "replace").strip()
        return json.loads(text) if text else {}
    except ValueError:
        return {"pid": "?", "host": "?", "note": "unreadable lock file"}


RENDER_PACKAGES = ("evids", "mitsuba", "drjit", "numpy", "colour-science", "opencv-python-headless")


NUMERIC_PACKAGES = ("numpy", "scipy", "torch", "drjit", "mitsuba", "opencv-python-headless", "scikit-learn")
SOURCE_ROOT = Path(__file__).resolve().parents[1]
DEPENDENCY_LOCK = "lock/requirements.txt"  # the committed lock (run.sh installs it)


@lru_cache(maxsize=1)
def environment_record() -> dict:
    """What a run folder records to be traced later: the git commit of the source tree (None when
    it is not a git checkout; ``+dirty`` when tracked files differ), the sha256 of the committed
    lock (None when the source tree has none) and the versions of evids and every numeric dependency."""
    import subprocess

    commit = None
    if (SOURCE_ROOT / ".git").exists():
        try:
            def git(*args: str) -> subprocess.CompletedProcess:
                return subprocess.run(["git", "-C", str(SOURCE_ROOT), *args], capture_output=True, text=True,
                                      timeout=20)

            head = git("rev-parse", "HEAD")
            if head.returncode == 0:
                dirty = git("status", "--porcelain", "--untracked-files=no").stdout.strip()
                commit = head.stdout.strip() + ("+dirty" if dirty else "")
        except (OSError, subprocess.SubprocessError):
            commit = None
    lock = SOURCE_ROOT / DEPENDENCY_LOCK
    lock_sha = hashlib.sha256(lock.read_bytes()).hexdigest() if lock.is_file() else None
    return {"git_commit": commit, "lock_sha256": lock_sha,
            "versions": package_versions(("evids", *NUMERIC_PACKAGES, "librosa"))}


def package_versions(packages: tuple[str, ...] = RENDER_PACKAGES) -> dict[str, str]:
    """Python and distribution versions, recorded in every written dataset or run."""
    out = {"python": platform.python_version()}
    for dist in packages:
        try:
            out[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            out[dist] = "not installed"
    return out


