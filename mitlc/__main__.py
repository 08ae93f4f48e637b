"""``python -m mitlc``: the same command as ``mitlc``."""

from mitlc.cli import main

if __name__ == "__main__":
    main()
