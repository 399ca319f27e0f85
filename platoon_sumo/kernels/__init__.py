"""Compiled kernels (numba ``@njit(cache=True)``) for the per-step hot paths.

Pure functions on arrays and numbers, no Python objects: route-path projection
(``path.py``), scan segmentation and rear fitting (``perception.py``) and the laser
follower's scan and trail geometry (``follower.py``). The modules that use them
(``platoon_sumo.path``, ``platoon_sumo.control.perception``,
``platoon_sumo.control.laser_follower``) keep the public API; the kernels do the same
arithmetic as the numpy code they replace, to floating-point rounding.

Each kernel is compiled on its first call and cached next to its module
(``__pycache__``, numba's ``cache=True``), so later processes load it instead of
compiling it again.
"""
