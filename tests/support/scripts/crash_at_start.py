"""A stand-in node executable that fails at start (for the runner's failure handling test)."""
import sys

print('simulated crash at start', file=sys.stderr, flush=True)
sys.exit(3)
