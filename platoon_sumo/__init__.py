"""platoon-sumo: laser-based vehicle platoons co-simulated with Eclipse SUMO."""

__version__ = "0.1.0"
