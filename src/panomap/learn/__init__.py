"""``panomap learn``: learn a camera in the browser (the paper's Fig. 4 and Fig. 7).

- :mod:`panomap.learn.session`: the state (image, circles, landmarks, camera, fit);
- :mod:`panomap.learn.server`: the web server and its JSON API;
- :mod:`panomap.learn.validate`: checks on every request;
- ``static/``: the page (plain HTML, CSS, JS).

The command itself is :mod:`panomap.cli.learn`.
"""
