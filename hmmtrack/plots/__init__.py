"""Figures: seaborn/matplotlib functions that take data or results and ``ax=None`` and return the Axes.

They compute nothing that the library does not already return; notebooks and
``hmmtrack reproduce`` only call them.
"""
