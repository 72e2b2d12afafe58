"""The generic head with its authored animation tables, built once per test session."""

import pytest


@pytest.fixture(scope="session")
def authored_head():
    from fmc.author import author_from_shapes
    from fmc.high_level import author_high_level
    from mpeg4.generic_head import load_generic_head

    head = load_generic_head()
    fat, _ = author_from_shapes(head)
    fat.update(author_high_level(head))
    head.fat = fat
    return head
