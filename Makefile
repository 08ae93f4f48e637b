# The two commands of the README: `make demo` (the main job on the shipped example) and
# `make test` (the whole suite, ruff and mypy). Each creates .venv and installs what it needs.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-stamp

.PHONY: system-deps demo test verify bench bench-check bench-shield bench-learn bench-throughput bench-bounded bench-task bench-sb3 bench-envs bench-sweep bench-teams lint docs docs-figures golden clean

$(STAMP): pyproject.toml | system-deps
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q torch==2.13.0
	$(BIN)/python -m pip install -q -e '.[dev,learn,sb3,sweep,envs,teams,docs]'
	touch $(STAMP)

# The main job on the shipped example: the paper's case 1 (a 5x5 grid MDP, task
# (!a U[5,10] a) & (!b U[15,20] b)). Check it exactly, learn it with tabular Q-learning (a few
# seconds), print the learned policy's success beside the optimum, and draw the run
# (learning curve, trajectories on the grid, the timed automaton) under build/case1-q/.
demo: system-deps $(STAMP)
	$(BIN)/mitlc check specs/paper/case1.yaml
	rm -rf build/case1-q
	$(BIN)/mitlc train specs/paper/case1.yaml --out build/case1-q
	$(BIN)/mitlc plot build/case1-q

# System packages, installed where missing: Graphviz's `dot` (it draws the PNGs of automata,
# products and runs) and Python's venv. apt-get as root or with password-less sudo; otherwise
# it says what to run.
system-deps:
	@PYTHON=$(PYTHON) scripts/system-deps

lint: $(STAMP)
	$(BIN)/ruff check mitlc tests bench
	$(BIN)/mypy

test: system-deps lint docs
	$(BIN)/pytest -q

# The documentation site (Sphinx, furo, MyST) under docs/_build/html, from a clean tree each time:
# warnings are errors, cross-references nitpicky, internal links checked; the CLI reference is
# generated from the Typer app (docs/cli.md) and the API reference from the docstrings. No network.
docs: $(STAMP) docs-figures
	$(BIN)/ruff check docs/conf.py docs/_ext
	$(BIN)/mypy --strict docs/conf.py docs/_ext
	rm -rf docs/_build/html docs/_build/doctrees
	$(BIN)/sphinx-build -q -W --keep-going -n -b html -d docs/_build/doctrees docs docs/_build/html

# The site's figures that come from shipped examples, drawn again (about 10 s, so `make docs`
# runs it first; seeded, so the same pictures): case 1's T-LDGBA (mitlc render), five greedy
# rollouts of a Q-learning run on case 1 (mitlc train, mitlc plot), and PointMaze Medium's
# distances (docs/figures/geodesic_distances.py). The learning curves of highway and DoorKey
# (docs/envs.md) come from trainings of minutes each and are not redrawn here.
docs-figures: $(STAMP)
	$(BIN)/mitlc render specs/paper/case1.mitl -o docs/figures/case1-automaton.png
	rm -rf build/docs-figures/case1-q
	$(BIN)/mitlc train specs/paper/case1.yaml --out build/docs-figures/case1-q -q
	$(BIN)/mitlc plot build/docs-figures/case1-q
	cp build/docs-figures/case1-q/trajectories.png docs/figures/case1-trajectories.png
	$(BIN)/python docs/figures/geodesic_distances.py

# Longer seeded checks (the slow marker, excluded from `make test`): 240,000 (formula, lasso)
# pairs against the reference semantics and 6,000 formulas against Spot (about 5 minutes).
verify: $(STAMP)
	$(BIN)/pytest -q -m slow

# Compile time and sizes beside Spot's translation (several minutes: Spot is given 60 s a formula),
# every formula's size beside Spot's deterministic automaton (bench/size_compare.py),
# issue 15's formulas (deadline sequences, office task) beside Spot with their targets, and the
# command line's start-up (CPU time of mitlc fmt, compile, --help) beside `python -c pass`.
bench: $(STAMP)
	$(BIN)/python bench/compile_bench.py
	-$(BIN)/python bench/size_compare.py
	$(BIN)/python bench/symbolic_bench.py
	$(BIN)/python bench/startup_bench.py

# Product build and exact solve of growing grids beside Storm on the exported model (a minute).
bench-check: $(STAMP)
	$(BIN)/python bench/check_bench.py --sizes 10,20,40,60,80,100
	$(BIN)/python bench/check_bench.py --memory --sizes 10,60,100

# Shielded beside audited tabular Q-learning on case 1, FrozenLake 8x8 and Taxi, three seeds
# (issue 27; about 7 minutes): violations, blocked actions, the exact success after training.
bench-shield: $(STAMP)
	$(BIN)/python bench/shield_bench.py --out build/bench-shield

# The paper's three case studies trained and measured beside the optimum (about 13 minutes).
bench-learn: $(STAMP)
	$(BIN)/python bench/learn_bench.py

# The task as a component (a minute): the batched monitor's letters per second beside the
# scalar one, the gymnasium wrapper's steps per second beside bare FrozenLake, and the lazy
# automaton beside the eager translation on a 12-room deadline sequence (with mitlc check).
bench-task: $(STAMP)
	$(BIN)/python bench/monitor_bench.py
	$(BIN)/python bench/wrapper_bench.py
	$(BIN)/python bench/lazy_bench.py

# Tabular steps per second: the vectorised simulator beside a gymnasium step loop (15 s).
bench-throughput: $(STAMP)
	$(BIN)/python bench/learn_throughput.py

# Compile time per state of F[0,k] a for k = 10^3..10^5 (linear), and how soon the runaway
# F[0,1000] G[0,1000] a is stopped at the default limits (about a minute and a half).
bench-bounded: $(STAMP)
	$(BIN)/python bench/bounded_bench.py

# Learners side by side (issue 13): mitlc's DQN beside SB3's DQN and PPO at the same env steps,
# on case 1 and on the continuous case 1 (about 15 minutes).
bench-sb3: $(STAMP)
	$(BIN)/python bench/sb3_bench.py --episodes 9000 --set dqn.crm=true --set dqn.target_update=50
	$(BIN)/python bench/sb3_bench.py --world specs/continuous/case1.yaml --episodes 10000 --set dqn.num_envs=32 --set dqn.target_update=25

# Env worlds side by side (issue 24): plain SB3 (state one-hot, pass/fail reward) beside mitlc's
# observation and shaping at the same env steps, 3 seeds each, on MiniGrid DoorKey and Empty,
# PointMaze, the continuous cases 1 and 2 and the paper's case 2 (with mitlc's tabular Q against
# its 120 s), IQM across tasks and the issue's targets. Hours on a CPU, over several sittings:
# Ctrl-C stops it, the same command goes on, and each finished run keeps its record in
# bench/results/envs (in git), so runs finished on another machine count (--steps-scale 0.1 for
# a quick look; bench/envs_bench.py --report prints the records' tables).
bench-envs: $(STAMP)
	$(BIN)/python bench/envs_bench.py --out build/bench-envs --jobs $(shell nproc)

# Sweeps at scale (issue 14): 20 seeds of case 1 and 10 of case 3 one after another, on Ray on
# this machine, and on a two-node Ray cluster started here (about 20 minutes).
bench-sweep: $(STAMP)
	$(BIN)/python bench/sweep_bench.py

# Teams of robots (issue 43): the exact joint optimum of two robots beside Storm on the same
# product, tabular learners beside it, and three robots in a warehouse (exact optimum in a child
# process with its peak memory; independent learners under the per-robot shield). About 10
# minutes and 8 GB on this machine (docs/teams.md).
bench-teams: $(STAMP)
	$(BIN)/python bench/teams_bench.py --out build/bench-teams

# Rewrite golden files from the current output; read `git diff tests/golden` before committing.
golden: $(STAMP)
	$(BIN)/pytest -q tests --update-golden

clean:
	rm -rf $(VENV) build dist .pytest_cache .mypy_cache .ruff_cache .hypothesis
