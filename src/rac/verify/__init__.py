"""``rac verify``: a query file answered by the engine. :func:`rac.verify.runner.verify` (and
:func:`~rac.verify.runner.run_queries`, which also returns the context) is the entry point; a
:class:`~rac.verify.context.Context` holds what every answer needs, one answerer per kind of query
receives it (:mod:`~rac.verify.symbolic`, :mod:`~rac.verify.statistical`, :mod:`~rac.verify.learning`),
and :mod:`rac.verify.report` holds the results and prints them.

May import: rac.compiler, core, lang, ir, check, model, runtime, engine, output, learning.
"""
