"""The episodes learners step: the fast vectorised simulator of a finite product
(:mod:`mitlc.learn.envs.vec`), the same as a gymnasium ``VectorEnv``
(:mod:`mitlc.learn.envs.vector`), and any ``VectorEnv`` of task-wrapped envs as the learners'
interface (:mod:`mitlc.learn.envs.envvec`)."""
