"""The live viewer: a web page that unwarps an image, a video or a live source on the browser's GPU
(WebGL2) through a pano-mapping table, as the user drags. See ``docs/viewer.md``."""
