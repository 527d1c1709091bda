"""Landmark learning (paper 2.1, Algorithm 1 and beyond): from an omni-image and landmarks to a camera.

- :mod:`.landmarks`: landmark pairs and their files;
- :mod:`.circles`: the image centre, cut-off disc and image circle found in an omni-image;
- :mod:`.fit`: :func:`fit_camera`, the fit of the camera model to the landmarks;
- :mod:`.report`: :class:`FitReport`, the fit's typed report, as a table stores it;
- :mod:`.pipeline`: landmarks to a pano-mapping table, the path ``panomap fit`` and the learn page share.
"""
