"""Other libraries' learners as backends of ``mitlc train``: Stable-Baselines3's training
(:mod:`mitlc.learn.backends.sb3`) and its trained policy loaded for ``eval`` and ``plot``
(:mod:`mitlc.learn.backends.sb3_policy`)."""
