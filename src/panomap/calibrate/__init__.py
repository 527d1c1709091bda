"""Landmark learning (paper 2.1, Algorithm 1 and beyond): from an omni-image and landmarks to a camera.

In the order :func:`calibrate_camera` takes its steps (``docs/architecture.md`` draws the chain):

- :mod:`.landmarks`: landmark pairs and their files;
- :mod:`.sources`: where the camera position, centre and radii came from (:class:`Source`);
- :mod:`.circles`: the image centre, cut-off disc and image circle found in an omni-image (a package, one
  idea a file);
- :mod:`.fit`: :func:`fit_camera`, the fit of the camera model to the landmarks, as its steps:
  :mod:`.noise` (observations and the whitened residuals), :mod:`.start` (axis, handedness, first values),
  :mod:`.selection` (model choice by cross-validation), :mod:`.outliers`, :mod:`.refine` (the one least
  squares, built from residual blocks), :mod:`.mount` (tilt and position);
- :mod:`.report`: :class:`FitReport`, the fit's typed report, as a table stores it; :mod:`.diagnosis`;
- :mod:`.make_table`: :func:`create_table`, a fitted camera's pano-mapping table (radii, range, size, checks);
- :mod:`.pipeline`: :func:`calibrate_camera`, landmarks (and an omni-image) to a table: the path ``panomap fit``,
  the learn page and the demo share.
"""
