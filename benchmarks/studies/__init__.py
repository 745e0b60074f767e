"""Study code: interval methods no command runs, importable by the studies and their tests."""
