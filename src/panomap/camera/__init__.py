"""The camera model: where a ray of azimuth theta and elevation rho lands in the omni-image.

- :mod:`.radial_models`: the radial model kinds (paper, odd1..odd5, poly2, poly3, unified), each
  declared once with its parameters, evaluation and fit, in one registry;
- :mod:`.radial`: :class:`RadialFunction` (a kind, its coefficients and the axis) and its fit;
- :mod:`.valid_range`: where a radial function is monotonic within the annulus;
- :mod:`.uncertainty`: the coefficients' covariance and the radius's standard error;
- :mod:`.model`: :class:`CameraModel` (centre, s, phi0, f_r, the viewing direction).
"""
