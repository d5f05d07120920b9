"""Settings for every test: hypothesis draws the same examples on every run (derandomized), so CI
sees what a developer saw and a failure reproduces as it is."""

from hypothesis import settings

settings.register_profile("repeatable", derandomize=True)
settings.load_profile("repeatable")
