"""Learning the camera from the checkerboards in its images: grids of straight, evenly spaced lines.

A checkerboard's inner corners are the crossings of two families of straight world lines, evenly
spaced and at right angles: beyond what straightness gives (:mod:`..lines`), their spacing fixes
where along each line every corner's ray lies, and the squares' right angles and equal sides fix
the scale of the elevations, which straightness alone leaves free.

Files:

- ``detect.py``: :class:`Board` and :func:`find_boards`, the inner corners of a checkerboard of any
  size in an omni-image, with their place on the grid; :func:`find_boards_each`, those of many images
  (in threads, the board learned from the first).
- ``fit.py``: the fit of the camera (radial model, centre) and of each board's pose from them.
"""
