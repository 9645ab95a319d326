"""The application over the library: the command line and its verbs.

``cli`` (argparse and the verbs), ``demo`` (``quatarray demo``), ``bench``
(``quatarray bench``), ``plot`` (``quatarray plot``), ``eval_verb``
(``quatarray eval``, over :mod:`quatarray.trajectory`). The library never
imports this package; the command line maps the library's exceptions to
exit statuses (:data:`quatarray.app.cli.EXIT_STATUS`).
"""
