"""The stage stores' suite runs on the store suite's fixtures (:mod:`store_fixtures`)."""

from store_fixtures import *  # noqa: F403
