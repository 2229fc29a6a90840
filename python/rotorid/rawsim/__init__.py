"""Simulated raw recordings for tests, demos and test planning.

``recordings``  what a DAQ records on the rig, exact for the linear model: steady dwells,
                coast-downs and impacts with run-out, remnant imbalance and noise
``keyphasor``   keyphasor pulse trains of many shapes (rectangular, trapezoid, RC-rounded,
                smooth, notch probe), duty cycles, noise, ringing and drift, written
                independently of rotorid's detector
``lab``         a second simulator: recordings as other DAQs make them (keyphasor shapes, a
                keyphasor mark at a known angle, channel delays, ADC quantization, one block per
                speed step)
"""

from .keyphasor import SHAPES, PulseShape, event_times, pulse_train
from .lab import lab_imbalance_recording
from .recordings import Runout, coastdown_recording, example_rig, imbalance_recording, impact_recording

__all__ = ["SHAPES", "PulseShape", "Runout", "coastdown_recording", "event_times", "example_rig",
           "imbalance_recording", "impact_recording", "lab_imbalance_recording", "pulse_train"]
