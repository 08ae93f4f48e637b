"""Learning policies on the product: tabular Q-learning, DQN and recurrent DQN."""
