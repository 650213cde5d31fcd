"""The store suite's fixtures (:mod:`store_fixtures`, shared with ``tests/stages``)."""

from store_fixtures import *  # noqa: F403
