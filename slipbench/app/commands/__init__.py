"""The `slipbench` commands, one module per command or command group; `slipbench.app.cli`
gathers them under the top-level group."""
