"""Calibrations in and out: other tools' camera models become pano-mapping tables, and back.

- :mod:`.models`: the external camera models, one file per model or family, one registry;
- :mod:`.readers`: calibration files, one file per format; :func:`.readers.read_calibration`;
- :mod:`.table_of_camera`: the table of an external model (:mod:`.frame`: its axis becomes the vertical);
- :func:`import_calibration` (:mod:`.api`), :func:`export_calibration` (:mod:`.export`, :mod:`.writers`).

The formats, their equations and conventions: ``docs/calibration-formats.md``.
"""
