"""Results folders that respect a user's files: no silent overwrite, a manifest, atomic writes.

Every command that writes files (``rotorid identify``, ``demo``, ``example``) goes through
:class:`ResultsFolder`:

- before anything is computed, a folder that already holds files the command would write is
  refused unless ``overwrite=True`` (``--overwrite``), naming a few of them;
- the folder gets a manifest (``rotorid-manifest.json``: command, time, rotorid version, files);
  with ``overwrite``, files that an earlier run listed there and this run does not write again
  (stale results, e.g. ``sync_vectors_3_*.csv`` of a 4-run analysis next to a 3-run one) are
  removed and reported; files rotorid did not write are never touched;
- every file is written to a temporary name in the folder and renamed into place, so an
  interrupted run leaves no half-written file.
"""

from __future__ import annotations

import contextlib
import datetime
import fnmatch
import json
import os
import uuid

from .errors import RotoridError

MANIFEST = "rotorid-manifest.json"


class ResultsFolder:
    """A folder a command writes its results to.

    ``patterns``: glob patterns of the files the command may write (checked before anything is
    computed, since some names depend on the data).

    Examples
    --------
    >>> import tempfile, os
    >>> d = tempfile.mkdtemp()
    >>> out = ResultsFolder(os.path.join(d, "res"), patterns=["*.csv"], command="doc example")
    >>> with out.atomic("a.csv") as tmp:
    ...     _ = open(tmp, "w").write("x\\n")
    >>> out.finish()   # stale files of an earlier run removed: none
    []
    >>> ResultsFolder(os.path.join(d, "res"), patterns=["*.csv"])
    Traceback (most recent call last):
    ...
    rotorid.errors.RotoridError: ... already holds results of an earlier run (a.csv); pass --overwrite (overwrite=True) to replace them
    """

    def __init__(self, path, *, patterns, overwrite: bool = False, command: str = ""):
        from ._validate import flag, path as _path, text

        self.path = os.path.abspath(str(_path("path", path)))
        self.overwrite = flag("overwrite", overwrite)
        self.command = text("command", command)
        if isinstance(patterns, str) or not isinstance(patterns, (list, tuple)) or \
                not all(isinstance(p, str) and p for p in patterns):
            raise RotoridError(f"patterns must be a list of file name patterns (e.g. ['*.csv']), got {patterns!r}")
        self.written: list[str] = []
        if os.path.exists(self.path) and not os.path.isdir(self.path):
            raise RotoridError(f"the output folder {self.path} is a file; choose another --out")
        try:
            os.makedirs(self.path, exist_ok=True)
        except OSError as exc:
            raise RotoridError(f"cannot create the output folder {self.path}: {exc.strerror or exc}") from None
        if not os.access(self.path, os.W_OK):
            raise RotoridError(f"the output folder {self.path} is not writable")
        self.previous = self._read_manifest()
        present = sorted(f for f in os.listdir(self.path)
                         if f == MANIFEST or any(fnmatch.fnmatch(f, p) for p in patterns))
        if present and not self.overwrite:
            shown = ", ".join(present[:4]) + (f" and {len(present) - 4} more" if len(present) > 4 else "")
            what = "results of an earlier run" if self.previous is not None else "files this command would replace"
            raise RotoridError(f"{self.path} already holds {what} ({shown}); pass --overwrite (overwrite=True) "
                               "to replace them")

    def _read_manifest(self):
        p = os.path.join(self.path, MANIFEST)
        if not os.path.isfile(p):
            return None
        try:
            with open(p, encoding="utf-8") as fh:
                data = json.load(fh)
            return [str(f) for f in data.get("files", [])]
        except (OSError, ValueError, AttributeError):
            return []

    def file(self, name: str) -> str:
        """Full path of a result file (use with :meth:`atomic` to write it)."""
        if not isinstance(name, str):
            raise RotoridError(f"result file name must be a string, got {name!r}")
        if os.path.basename(name) != name or name in ("", ".", "..", MANIFEST):
            raise RotoridError(f"result file name {name!r} is not a plain file name")
        return os.path.join(self.path, name)

    @contextlib.contextmanager
    def atomic(self, name: str):
        """Yield a temporary path; it becomes ``name`` in the folder only if the block succeeds."""
        with _replacing(self.file(name)) as tmp:
            yield tmp
        if name not in self.written:
            self.written.append(name)

    def record(self, name: str):
        """Note a file written by other means (e.g. a copied data set) in the manifest."""
        self.file(name)  # a plain file name, like the files the folder writes itself
        if name not in self.written:
            self.written.append(name)

    def finish(self) -> list:
        """Write the manifest; remove the stale files of an earlier run and return their names."""
        stale = []
        for f in self.previous or []:
            p = os.path.join(self.path, os.path.basename(f))
            if f not in self.written and os.path.isfile(p):
                os.remove(p)
                stale.append(f)
        from . import __version__

        manifest = {"command": self.command, "time": datetime.datetime.now().isoformat(timespec="seconds"),
                    "rotorid": __version__, "files": self.written}
        with _replacing(os.path.join(self.path, MANIFEST)) as tmp, open(tmp, "w", encoding="utf-8") as fh:
            json.dump(manifest, fh, indent=1)
        return stale


@contextlib.contextmanager
def _replacing(final: str):
    """A temporary path beside ``final`` (same extension, so writers that go by it work) that
    replaces ``final`` only if the block succeeds."""
    folder, name = os.path.split(final)
    stem, ext = os.path.splitext(name)
    tmp = os.path.join(folder, f".{stem}.{os.getpid()}.{uuid.uuid4().hex[:8]}.tmp{ext}")
    try:
        yield tmp
        os.replace(tmp, final)
    except BaseException:
        with contextlib.suppress(OSError):
            os.remove(tmp)
        raise
