"""The learners: tabular Q-learning (on the product, or on a discrete observation), DQN and the
recurrent DQN with their networks, counterfactual experience, and the learners of a world that
is not finite (:mod:`mitlc.learn.learners.open_world`); :mod:`mitlc.learn.learners.base` is the
interface every learner and policy has."""
