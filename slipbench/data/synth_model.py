"""The simulation's version, apart from :mod:`synth` so that finding the default dataset's
cache folder (the first thing a newcomer's first command says) imports neither numpy nor
pandas."""

MODEL_VERSION = 4  # bump when the simulation changes, so cached datasets are regenerated
