"""The ``rac`` command: :mod:`rac.cli.main` (check, compile, fmt and the parser), the engine's
commands (:mod:`rac.cli.engine`: verify, simulate, render, preanalyse, learn, experiment), ``rac sweep``
(:mod:`rac.cli.sweep`), ``rac new`` (:mod:`rac.cli.new`) and what they share (:mod:`rac.cli.common`:
exit codes, reading a `.ra` file, atomic writes).

May import: rac, rac.compiler, core, lang, ir, check, model, runtime, targets, engine, output, learning, verify,
studies, sweep.
"""
