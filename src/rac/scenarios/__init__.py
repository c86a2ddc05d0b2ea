"""Scenarios rac builds itself with commonroad-io (the examples and the tests develop against them).

- :mod:`rac.scenarios.intersection`: the paper's experiment — the ego enters a four-way
  intersection from the south, turns left and drives to a goal area on the west arm while other
  vehicles cross (``python -m rac.scenarios.intersection OUT.xml``).

The modules import commonroad-io when they are imported; :mod:`rac.scenario` does not.
"""
