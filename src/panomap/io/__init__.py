"""Images, maps and pictures on disk: the edges' file formats (the table's own file is in :mod:`panomap.table`)."""
