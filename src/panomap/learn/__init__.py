"""``panomap learn``: learn a camera in the browser (the paper's Fig. 4 and Fig. 7).

- :mod:`panomap.learn.session`: the state (image, circles, landmarks, camera, fit);
- :mod:`panomap.learn.server`: the web server and its JSON API;
- :mod:`panomap.learn.validate`: checks on every request;
- :mod:`panomap.learn.cli`: the command; ``static/``: the page (plain HTML, CSS, JS).
"""

from __future__ import annotations

# The command reuses panomap.cli's option types and panomap.cli registers it: importing the
# CLI first keeps that order whichever module is imported first.
from .. import cli as _cli  # noqa: F401
