"""rotorid's native recording file: a NumPy ``.npz`` archive (layout in the package docstring)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from ..errors import RotoridError
from ..recording import Recording
from ._common import FORMAT_NAME, FORMAT_VERSION, _atomic_write, _cannot, _describe, _json_default, _Raw, _Read

__all__ = ["save_recording"]


def save_recording(rec: Recording, path) -> None:
    """Write ``rec`` in the native format (see :mod:`rotorid.io`); ``path`` is used as given.

    Examples
    --------
    >>> import numpy as np, tempfile, os
    >>> from rotorid.recording import Recording
    >>> from rotorid.io import save_recording, load_recording
    >>> path = os.path.join(tempfile.mkdtemp(), "run.npz")
    >>> save_recording(Recording(1000.0, {"x1": np.zeros(8)}), path)
    >>> load_recording(path).fs_hz
    1000.0
    """
    if not isinstance(rec, Recording):
        raise RotoridError(f"rec must be a Recording, got {type(rec).__name__}")
    try:
        meta_json = json.dumps(rec.meta, default=_json_default, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise RotoridError(f"cannot write {path}: Recording.meta is not JSON-serializable ({exc})") from None
    arrays = {f"ch_{name}": np.asarray(data, dtype=np.float64) for name, data in rec.channels.items()}
    arrays.update(format=np.array(FORMAT_NAME), format_version=np.array(FORMAT_VERSION, dtype=np.int64),
                  fs_hz=np.array(rec.fs_hz, dtype=np.float64), t0_s=np.array(rec.t0_s, dtype=np.float64),
                  meta_json=np.array(meta_json), units_json=np.array(json.dumps(rec.units)),
                  source=np.array(json.dumps(rec.source)))
    # through an open file, so that numpy does not append ".npz" to a path that lacks it
    if Path(str(path)).suffix.lower() in (".csv", ".txt", ".asc", ".tdms", ".uff", ".unv"):
        raise RotoridError(f"cannot write {path}: save_recording writes rotorid's native NPZ, and this name says "
                           f"{Path(str(path)).suffix}; use save_csv, save_tdms or save_uff58, or a .npz name")
    with _atomic_write(path) as tmp, open(tmp, "wb") as fh:
        np.savez_compressed(fh, **arrays)


def _read_native(path: Path) -> tuple[_Read, str]:
    """The channels and meta of a native file, and the source it stores."""
    try:
        archive = np.load(path, allow_pickle=False)
    except Exception as exc:  # numpy raises OSError, ValueError, BadZipFile, EOFError ... on bad files
        raise _cannot(path, "native", _describe(exc)) from None
    if not hasattr(archive, "files"):  # a bare .npy array, not an archive
        raise _cannot(path, "native", "it is a single array, not an .npz archive")
    with archive:
        try:
            if "format" not in archive.files:
                raise _cannot(path, "native", "it has no 'format' entry (not written by save_recording)")
            fmt = str(archive["format"])
            if fmt != FORMAT_NAME:
                raise _cannot(path, "native", f"format is {fmt!r}, expected {FORMAT_NAME!r}")
            missing = [k for k in ("format_version", "fs_hz", "t0_s", "meta_json", "units_json", "source")
                       if k not in archive.files]
            if missing:
                raise _cannot(path, "native", f"entries {missing} are missing")
            version = archive["format_version"]
            if version.shape != () or version.dtype.kind not in "iu" or int(version) != FORMAT_VERSION:
                raise _cannot(path, "native", f"format_version {version!r} is not supported "
                                              f"(this rotorid reads version {FORMAT_VERSION})")
            fs = float(archive["fs_hz"])
            t0 = float(archive["t0_s"])
            file_meta = json.loads(str(archive["meta_json"]))
            units = json.loads(str(archive["units_json"]))
            source = json.loads(str(archive["source"]))
            if not isinstance(file_meta, dict) or not isinstance(units, dict) or not isinstance(source, str):
                raise _cannot(path, "native", "meta_json and units_json must hold JSON objects and source a "
                                              "JSON string")
            raws = []
            for key in archive.files:
                if key.startswith("ch_"):
                    name, data = key[3:], archive[key]
                    if data.ndim != 1 or data.dtype.kind != "f":
                        raise _cannot(path, "native", f"channel {name!r} is not a 1-D float array "
                                                      f"(shape {data.shape}, dtype {data.dtype})")
                    raws.append(_Raw(name, name, data.astype(np.float64, copy=False), units.get(name) or None,
                                     fs, t0))
        except RotoridError:
            raise
        except Exception as exc:  # corrupt members (CRC, truncation), bad JSON, bad scalars
            raise _cannot(path, "native", _describe(exc)) from None
    if not math.isfinite(fs) or fs <= 0:
        raise _cannot(path, "native", f"fs_hz is {fs!r}")
    if not raws:
        raise _cannot(path, "native", "it holds no channel (no 'ch_<name>' entry)")
    return _Read(raws, file_meta), source
