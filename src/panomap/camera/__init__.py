"""The camera model: where a ray of azimuth theta and elevation rho lands in the omni-image.

- :mod:`.radial`: the radial stretching functions r = f_r(rho), their fits and valid range;
- :mod:`.model`: :class:`CameraModel` (centre, s, phi0, f_r).
"""
