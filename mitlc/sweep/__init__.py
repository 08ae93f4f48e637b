"""Sweeps: many seeds, learners, worlds and settings, run on Ray Tune (locally or on a
cluster) and reported with rliable's statistics (the extra ``mitlc[sweep]``)."""
