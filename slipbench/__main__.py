"""`python -m slipbench ...`: the `slipbench` command run by the interpreter, through the same
``main`` as the console script (same messages, same exit codes)."""

from slipbench.app.cli import main

if __name__ == "__main__":
    main()
