"""Figures: seaborn/matplotlib functions that take data or results and return the Axes.

Each takes ``ax=None`` (a new figure when omitted).

They compute nothing that the library does not already return; notebooks and
``hmmtrack reproduce`` only call them.
"""
