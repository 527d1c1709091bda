"""Views (paper 2.3 and beyond): what ray each output pixel sees, the maps that follow, and view specs."""
