"""How good a learned policy is: ``evaluate(run_directory)``
(:mod:`mitlc.learn.evaluation.evaluate`),
the one Monte-Carlo estimate of every world (:mod:`mitlc.learn.evaluation.montecarlo`), the
exact success of a memoryless policy on a finite product (:mod:`mitlc.learn.evaluation.exact`)
and the greedy rollouts the plots draw (:mod:`mitlc.learn.evaluation.trajectories`)."""
