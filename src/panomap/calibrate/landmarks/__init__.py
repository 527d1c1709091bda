"""Learning the camera from landmarks (paper 2.1, Algorithm 1 and beyond): pairs of a pixel and a measured position.

Files, lowest first (each imports only files before it, and the core, circles, lines and boards below it):

- ``pairs.py``: :class:`Landmarks` and their files (CSV, JSON);
- ``outliers.py``: landmarks that disagree dropped; model and inliers chosen together;
- ``mount.py``: the tilt and the position, kept where held-out errors say the landmarks support them;
- ``joint.py``: the image's straight lines joined to the final refinement (one residual block);
- ``viewpoint.py``: a mirror without a single viewpoint: the caustic's size fitted to the landmarks;
- ``fit.py``: :func:`fit_camera`, the fit as its steps, and :class:`CameraFit`;
- ``diagnosis.py``: what the residuals' pattern says is wrong;
- ``table.py``: :func:`create_table`, a landmark fit's pano-mapping table (radii, range, size, checks);
- ``pipeline.py``: :func:`calibrate_camera`, landmarks (and an omni-image) to a table.
"""
