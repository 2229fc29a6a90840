"""Reading and writing recordings: rotorid's native file and the lab formats delimited text
(CSV/TXT), NI TDMS and UFF 58.

:func:`load_recording` reads any of them into a :class:`~rotorid.recording.Recording` (float64,
SI units, canonical channel names); :func:`load_segmented` reads a recording saved as blocks
(one file or one TDMS group per block) into a :class:`~rotorid.recording.SegmentedRecording`;
:func:`save_recording` writes the native file; :func:`save_csv`, :func:`save_tdms`,
:func:`save_tdms_segmented` and :func:`save_uff58` write lab files, for converting data and for
tests; :func:`list_groups` lists the groups of a TDMS file.

The package has a module per format: :mod:`~rotorid.io.native`, :mod:`~rotorid.io.delimited`,
:mod:`~rotorid.io.tdms`, :mod:`~rotorid.io.uff`, plus :mod:`~rotorid.io.clipping`.

Native format (``.npz``, format_version 1)
------------------------------------------
A NumPy ``.npz`` archive written with ``np.savez_compressed`` and readable with
``np.load(path, allow_pickle=False)``. Entries (all 0-d arrays except the channels):

    format          str      "rotorid-recording"
    format_version  int      1
    fs_hz           float64  sample rate, Hz
    t0_s            float64  time of the first sample, s
    ch_<name>       float64  1-D, one per channel (``Recording.channels[name]``), SI units
    meta_json       str      JSON of ``Recording.meta`` (a JSON object)
    units_json      str      JSON object: channel name -> unit
    source          str      JSON string: ``Recording.source`` (where the data came from)

A reader refuses a file whose ``format`` or ``format_version`` differ. Loading a native file
without a channel_map gives back the saved Recording exactly, non-canonical channels included;
its ``source`` is the stored one (or the file's path if none was stored).

Lab files
---------
``.csv .txt .asc``  delimited text (:mod:`rotorid.io.delimited`): preamble, header with units
                    (``name [unit]``, ``name (unit)``), separator ``,`` ``;`` tab or whitespace and
                    decimal mark found automatically (``skip_rows=``, ``sep=``, ``decimal=``
                    override); a time column (``t``, ``time``, ``Time (s)``, ``Time [ms]``...,
                    or ``time_column=``) with uniform steps gives fs = (n-1)/(t[-1]-t[0]) and t0;
                    else a ``Sample rate: ... Hz`` preamble line, else ``fs_hz``. A ``.dat`` file
                    is read this way with ``fmt="csv"`` (the extension is also used for binary
                    files, so it is not taken for text).
``.tdms``           (:mod:`rotorid.io.tdms`) every channel of every group, addressed as
                    ``"Group/Channel"`` or as ``"Channel"`` when no other group has a channel of
                    that name; ``group=`` reads one group. Sample rate from ``wf_increment``
                    (``fs_hz`` only for channels without one), start time from
                    ``wf_start_offset``, unit from ``unit_string``; a time channel (by name,
                    timestamps or a time unit, or ``time_column=``) is the group's time base.
``.uff .unv``       (:mod:`rotorid.io.uff`, pyuff) every type-58 time series (function type 0 or
                    1, real data), addressed by ``id1`` or as ``"<node>:<dir>"`` (``"3:+X"``);
                    rate from the abscissa, unit from the ordinate axis units label.

How lab channels become Recording channels (``load_recording``'s ``channel_map``)::

    channel_map = {"Prox DE X": {"to": "x1", "unit": "mil", "delay_s": 2.5e-4},
                   "Hammer":    {"to": "force", "unit": "lbf", "scale": 0.1}}  # file in mV, 10 mV/lbf

Each entry maps a lab channel to a canonical name (``recording.KNOWN``) and says how to get SI
values: ``value_SI = (raw * scale + offset) * units.factor(unit, quantity)``, the quantity
following from the canonical name (displacements: length, force: force, kp: voltage,
px*/py*: acceleration). ``scale`` (sensor sensitivity) defaults to 1, ``offset`` to 0; without
``unit`` the unit the file states is used, else SI is assumed. A unit of the wrong quantity
raises. ``delay_s`` (default 0, |delay_s| < 1 s) is the time by which the channel's signal lags
the true quantity (anti-alias filter group delay, cable); the data are not shifted, non-zero
delays are stored in meta ``"channel_delays_s"`` ({canonical name: s}) for the processing to
correct. Channels the file names canonically (``x1``, ...) are used without an entry, with the
file's unit or SI. Every other channel is dropped with one warning that lists them all; a mapped
channel missing from the file raises, naming it and what the file has. The Recording's meta then
records, under ``"channel_sources"``, which file channel, unit, scale and offset fed each channel.
``angle_deg`` (probes mounted at an angle; degrees from +x toward +y the probe measures along, x
0 and y 90 by default; API 670's 45° either side of vertical are 45 and 135) resolves the two
channels of a plane (x1/y1, x2/y2, px1/py1, px2/py2) into its x and y motion:
``x = (sin b u_a - sin a u_b) / sin(b - a)``, ``y = (cos a u_b - cos b u_a) / sin(b - a)``; both
channels must be mapped, at least 20° from parallel, with the same ``delay_s``.

Any file that cannot be parsed raises ``RotoridError("cannot read <path> as <format>: <reason>")``;
every error about a file names it. Options that do not apply to a file's format (e.g. ``group=``
for a CSV file) raise. Displacement and force channels are checked for clipping on load
(:func:`check_clipping`).

Examples
--------
>>> import numpy as np, os, tempfile
>>> from rotorid.recording import Recording
>>> from rotorid import io
>>> path = os.path.join(tempfile.mkdtemp(), "run.tdms")
>>> io.save_tdms(Recording(2000.0, {"x1": np.zeros(100)}), path, group="Run 1", names={"x1": "Prox DE X"},
...              units={"x1": "mil"})
>>> rec = io.load_recording(path, group="Run 1", channel_map={"Prox DE X": {"to": "x1"}})
>>> rec.fs_hz, rec.units["x1"], rec.meta["channel_sources"]["x1"]["unit"]
(2000.0, 'm', 'mil')
"""

from ._common import FORMAT_NAME, FORMAT_VERSION, FORMATS, QUANTITY
from ._load import load_recording, load_segmented
from .clipping import CLIP_CHECKED, CLIP_MIN_RUN, check_clipping
from .delimited import save_csv
from .native import save_recording
from .tdms import list_groups, save_tdms, save_tdms_segmented
from .uff import save_uff58

__all__ = ["FORMAT_NAME", "FORMAT_VERSION", "FORMATS", "QUANTITY", "check_clipping", "list_groups", "load_recording",
           "load_segmented", "save_csv", "save_recording", "save_tdms", "save_tdms_segmented", "save_uff58"]
