"""The co-simulation loop's stages, the step context they share, and the SUMO port.

`platoon_sumo.cosim` runs them in order; each module here is one stage or its data.
"""
