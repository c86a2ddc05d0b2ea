"""rac's own verification engine: explore the model's state space, decide queries with Storm."""
