"""Filtering of trajectories (zero-phase low-pass Butterworth, as Pose2Sim offers)."""

from toolkit.filtering.butterworth import ButterworthFilter, butterworth_lowpass

__all__ = ["ButterworthFilter", "butterworth_lowpass"]
