"""Experiments: accuracy harnesses and the papers' tables reproduced."""
