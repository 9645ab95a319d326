# The guide's pages are doctested (pyproject's --doctest-glob); the Sphinx
# configuration and the gallery's scripts are not test modules.
collect_ignore = ["conf.py"]
collect_ignore_glob = ["pyplots/*", "_build/*", "generated/*"]
