"""Replaying a program on the machine model: vc and fz along the cut, where the spindle lags."""
