"""Learning under a shield: episodes of the model, tabular Q-learning, gymnasium environments."""
