"""A user's plug-in module that fails while being imported (a missing dependency)."""

import a_dependency_that_is_not_installed  # noqa: F401


class BrokenController:
    pass
