"""From raw waveforms to synchronous vectors and FRFs.

``keyphasor``  once-per-revolution event times, whatever the pulse shape (state levels, Schmitt
               trigger, equivalent-time edge timing, missing/extra pulses, mark angle, delay)
``order``      1X (and nX) vectors by computed order tracking: every revolution resampled at P
               uniform angles from its own keyphasor pulses (4-point cubic, Rust core), orders
               read off the revolution DFTs; steady segments, coast-down blocks, segmented
               recordings, slow-roll run-out
``impacts``    impact detection (double hits, overloads), the report's time-domain run-out
               filter (Rust core), force and exponential windows, H1 FRFs with coherence

Phase convention: x(t) = Re(X e^{j theta(t)}) with theta = 0 at the keyphasor's rotor angle zero.
"""

from .impacts import (FRF, Impact, detect_impacts, exponential_window, force_window, frf_h1, revolution_signature,
                      runout_filter)
from .keyphasor import Keyphasor, KeyphasorError, keyphasor_times, state_levels
from .order import SyncTrack, slow_roll_vector, steady_segments, track

__all__ = ["FRF", "Impact", "Keyphasor", "KeyphasorError", "SyncTrack", "detect_impacts", "exponential_window",
           "force_window", "frf_h1", "keyphasor_times", "revolution_signature", "runout_filter", "slow_roll_vector",
           "state_levels", "steady_segments", "track"]
