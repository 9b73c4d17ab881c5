"""How thoroughly the property tests draw: ``HYPOTHESIS_PROFILE=thorough`` asks for thousands of
fresh examples (tests/conftest.py loads the profile)."""

from __future__ import annotations

import os

THOROUGH = os.environ.get("HYPOTHESIS_PROFILE") == "thorough"
