"""Seeds: every random number of a run derives from one non-negative integer seed, at most
``SEED_MAX`` = 2**63 - 1 (a signed 64-bit integer: what a stored study keeps), so that a case
the command line runs is one the service can store."""

SEED_MAX = 2**63 - 1
