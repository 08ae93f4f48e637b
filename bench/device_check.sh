#!/usr/bin/env bash
# The checks that need a GPU, as one script for a lent CUDA machine (the workplace's device
# tool; CI never has one). That machine has Python 3.12 with a CUDA build of torch and reaches
# no registry, so mitlc's other needs travel as wheels in .whl/ (ignored by git), made here by:
#
#   python3 -m pip download --no-deps --only-binary=:all: --python-version 3.12 \
#     --implementation cp --platform manylinux2014_x86_64 -d .whl lark==1.3.1 \
#     gymnasium==1.4.0 farama-notifications==0.0.6 pydantic==2.14.4 pydantic_core==2.50.5 \
#     annotated-types==0.8.0 typing-inspection==0.4.5 typing_extensions==4.16.0 graphviz==0.21 \
#     stable-baselines3==2.9.2 sb3-contrib==2.9.2
#
# and the call is `bash bench/device_check.sh` with `.whl` carried. It writes its logs to $OUT
# (or build/device-check here) and prints:
#   1. tests/test_cuda.py: every deep learner and SB3 backend on --device cuda;
#   2. the CPU tests of devices (test_deep, test_sb3_continuous) on a machine that has CUDA;
#   3. the env steps per second of one short run of each learner on cuda and on cpu.
set -uo pipefail
out="${OUT:-build/device-check}"
mkdir -p "$out"
if [ -d .whl ]; then
  python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade \
    --target /tmp/site .whl/*.whl || exit 1
  export PYTHONPATH="/tmp/site:$PWD"
fi
export PYTHONUNBUFFERED=1 MPLBACKEND=Agg
nvidia-smi -L
python3 -c "import torch; print('torch', torch.__version__, 'cuda', torch.cuda.is_available())"

echo "== 1. tests/test_cuda.py"
timeout 300 python3 -m pytest -q -p no:cacheprovider -rs tests/test_cuda.py 2>&1 | tee "$out/cuda.log"
echo "== 2. the CPU tests of devices, on a machine with CUDA"
timeout 200 python3 -m pytest -q -p no:cacheprovider -rs tests/test_deep.py \
  tests/test_sb3_continuous.py 2>&1 | tee "$out/cpu-tests.log"
echo "== 3. env steps per second, cuda against cpu"
timeout 200 python3 bench/device_speed.py 2>&1 | tee "$out/speed.log"
