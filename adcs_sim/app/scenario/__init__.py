"""Scenario files: reading them (rcl's parser), the whole-scenario checks, the node registry and seeds."""
