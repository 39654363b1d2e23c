"""The run driver: set-up, the run loop and what happens between steps (output, checkpoints, measures, signals)."""
