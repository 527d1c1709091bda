"""Learning the camera: from an omni-image and its evidence (landmarks, straight lines, checkerboards) to a table.

A package per method over one shared core; every import points down (``docs/architecture.md`` draws it,
``tests/test_layers.py`` checks it), lowest first:

- :mod:`.core`: what the methods share: where values came from (:class:`Source`), the noise model, the
  refiner built from residual blocks, the starting values and model choice by cross-validation, the typed
  reports (:class:`FitReport`, the line fit's), the table's range;
- :mod:`.circles`: the image centre, cut-off disc and image circle found in an omni-image;
- :mod:`.lines`: the camera learned from the straight lines in its images;
- :mod:`.boards`: the camera learned from checkerboards (or from lines, where boards are too few);
- :mod:`.landmarks`: the camera fitted to landmarks (paper 2.1, Algorithm 1): :func:`fit_camera`, the table
  made from it, and :func:`calibrate_camera`, the path ``panomap fit``, the learn page and the demo share;
  with an image, its lines join the fit;
- :mod:`.pictures`: :func:`learn_from_images`, pictures' lines and checkerboards to a table.
"""
