"""``panomap video``'s pipeline: decode once, remap every frame into several views, encode each."""
