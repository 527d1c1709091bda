"""Learning the camera from the straight lines in its images (no landmarks, no tape measure).

Files:

- ``arcs.py``: :class:`EdgeArc` and :func:`find_arcs`, the smooth edge curves of an omni-image
  inside its usable annulus (sub-pixel edge points, linked, split at corners), each a candidate
  image of one straight world line. Straightness is not decided here: that needs the camera model.
- ``fit.py``: the fit of the camera (radial model, centre, tilt) from those arcs.
"""
