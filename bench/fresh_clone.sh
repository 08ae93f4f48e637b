#!/usr/bin/env bash
# The README's two commands on a fresh clone, as a new user runs them: `make demo`, then
# `make test` (with CI=true), each timed, in a clone of this repository's HEAD under a
# temporary directory. A fresh machine has no Graphviz: where `dot` is installed, pass
# --remove-graphviz to remove the Debian package first (root or sudo), so that the Makefile's
# own set-up is what installs it again. Usage: bench/fresh_clone.sh [--remove-graphviz] [--keep]
set -euo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
remove=0 keep=0
for arg in "$@"; do
  case $arg in
    --remove-graphviz) remove=1 ;;
    --keep) keep=1 ;;
    *) echo "usage: $0 [--remove-graphviz] [--keep]" >&2; exit 2 ;;
  esac
done

if command -v dot >/dev/null 2>&1; then
  if [ $remove -eq 0 ]; then
    echo "dot is installed here ($(command -v dot)): pass --remove-graphviz to start without it" >&2
    exit 2
  fi
  sudo=(); [ "$(id -u)" -eq 0 ] || sudo=(sudo -n)
  "${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get remove -y -qq graphviz >/dev/null
  hash -r
  if command -v dot >/dev/null 2>&1; then
    echo "dot is still on PATH after removing the graphviz package: $(command -v dot)" >&2
    exit 2
  fi
fi

work=$(mktemp -d /tmp/mitlc-fresh.XXXXXX)
[ $keep -eq 1 ] || trap 'rm -rf "$work"' EXIT
git clone -q "$repo" "$work/mitlc"
cd "$work/mitlc"
echo "fresh clone of $(git rev-parse --short HEAD) in $work/mitlc; dot: $(command -v dot || echo absent)"

run() {
  local name=$1; shift
  local start=$SECONDS rc=0
  "$@" >"$work/$name.log" 2>&1 || rc=$?
  printf '| %-10s | %4s | %6d s |\n' "$name" "$rc" $((SECONDS - start)) >>"$work/table"
  tail -n 5 "$work/$name.log"
  return 0
}
run "make demo" make demo
run "make test" env CI=true make test
echo
echo "| command    |   rc |  wall |"
echo "|------------|------|-------|"
cat "$work/table"
[ -f build/case1-q/learning_curve.png ] && echo "demo plots: $(ls build/case1-q/*.png | xargs -n1 basename | tr '\n' ' ')"
