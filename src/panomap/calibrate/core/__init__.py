"""What every way of learning the camera shares: noise, refiner, model choice, report, the table's range.

Files, lowest first (each imports only files before it; ``tests/test_layers.py`` checks it):

- ``sources.py``: :class:`Source` and :class:`Origin`, where each value a table records came from;
- ``line_report.py``: :class:`LineFitReport`, what a fit to straight lines saw (used by the lines', the
  boards' and the joint fit);
- ``report.py``: :class:`FitReport`, the typed report of any fit, as a table stores it;
- ``table_range.py``: the world elevations a tilted camera's table spans, and its default size limit;
- ``noise.py``: :class:`Observations` (rays and pixels in the camera's frame) and the noise model, the one
  whitened-residual function;
- ``refine.py``: the one least squares of f_r, phi0 and optionally centre, tilt and position, built from
  residual blocks, returning the covariance;
- ``start.py``: the axis, the handedness and the first values of f_r and phi0 with the centre fixed;
- ``selection.py``: the radial model chosen by cross-validation; held-out errors of a refined mount.

Nothing here imports a method's package (:mod:`..circles`, :mod:`..lines`, :mod:`..boards`, :mod:`..landmarks`).
"""
