"""The UPPAAL target: a UPPAAL 5 model (``.xml``) of a reward automaton, alone or in the scenario of
its ``model`` block, and its queries (``.q``).

- :mod:`~rac.targets.uppaal.automaton` — the automaton-alone model: its generator and the entry points
  (``generate_uppaal``, ``vocabulary``, ``queries_path``, ``UppaalError``, ``UppaalModel``);
- :mod:`~rac.targets.uppaal.model` — the whole model in the scenario (``generate_uppaal_model``);
- :mod:`~rac.targets.uppaal.significands` — numbers as significands: inputs' values, accruals, E0801;
- :mod:`~rac.targets.uppaal.labels` — the reward automaton's labels: rates, guards, updates, end clauses;
- :mod:`~rac.targets.uppaal.processes` — the Timer, Environment and reward automaton templates;
- :mod:`~rac.targets.uppaal.declarations` — the scenario model's data and C functions as declarations;
- :mod:`~rac.targets.uppaal.query` — queries and bindings in UPPAAL's three dialects;
- :mod:`~rac.targets.uppaal.expr` — literals, guards and linear forms in UPPAAL syntax;
- :mod:`~rac.targets.uppaal.names` — UPPAAL's reserved words and the emitted model's names;
- :mod:`~rac.targets.uppaal.layout` — templates, locations, transitions, and the jinja2 environment;
- ``templates/`` — the jinja2 templates of the XML skeleton, the declarations and the C functions.
"""
