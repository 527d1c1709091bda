"""``python -m panomap``: the command line."""

from panomap.cli import main

main()
