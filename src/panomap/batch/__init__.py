"""``panomap batch``: many inputs (several cameras, images and videos) unwarped on Dask, resumably."""
