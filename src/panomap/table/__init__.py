"""The pano-mapping table (paper 2.2, Algorithm 2): what a table is, never how it is made.

- :mod:`.table`: :class:`PanoMappingTable` (entries, project, unproject) and
  :func:`fill_entries` (Algorithm 2);
- :mod:`.sampling`: reading the table at any rays through ``cv2.remap``;
- :mod:`.file`: the ``.npz`` file (save, load and its checks).

Tables are made from a fitted camera in :mod:`panomap.calibrate.landmarks.table`.
"""
