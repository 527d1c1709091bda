"""The ``panomap`` command line: an edge that parses input, calls the library and reports.

:mod:`.app` holds the command group and registers every command; each other
module is one group of commands. The library never imports this package.
"""
