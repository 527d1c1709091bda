"""Landmark learning (paper 2.1, Algorithm 1 and beyond): from an omni-image and landmarks to a camera.

- :mod:`.landmarks`: landmark pairs and their files;
- :mod:`.circles`: the image centre, cut-off disc and image circle found in an omni-image;
- :mod:`.fit`: :func:`fit_camera`, the fit of the camera model to the landmarks;
- :mod:`.make_table`: :func:`create_table`, a fitted camera's pano-mapping table (radii, range, size, checks);
- :mod:`.report`: :class:`FitReport`, the fit's typed report, as a table stores it;
- :mod:`.sources`: where the camera position, centre and radii came from (:class:`Source`);
- :mod:`.pipeline`: :func:`calibrate_camera`, landmarks (and an omni-image) to a table: the path ``panomap fit``,
  the learn page and the demo share.
"""
