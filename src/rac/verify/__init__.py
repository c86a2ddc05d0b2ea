"""``rac verify``: a query file answered by the engine. :func:`rac.verify.runner.run_queries` is
the entry point; a :class:`~rac.verify.runner.Context` holds what every answer needs and one answerer
per kind of query (symbolic, statistical, learning) answers it; :mod:`rac.verify.report` prints.

May import: rac.compiler, core, lang, ir, check, model, runtime, engine, output, learning.
"""
