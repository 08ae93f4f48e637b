"""The run directory: its files and locks (:mod:`mitlc.learn.rundir.files`), checkpoints of data
only (:mod:`mitlc.learn.rundir.checkpoint`), the check of a loaded state against fresh objects
(:mod:`mitlc.learn.rundir.state`), and the counters, metrics lines and result of a run as it
goes (:mod:`mitlc.learn.rundir.runlog`)."""
