"""The reference report's Section 5 feature catalogue beyond the C core's streaming features:
offline features on numpy/scipy, each with the low-dimensional metric `dynval validate` uses."""
