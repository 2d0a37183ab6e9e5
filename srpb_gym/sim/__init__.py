"""The 2-D world: static walls, walking people, differential-drive robots and their sensors.

Geometry kernels shared by the simulator and the sensors live in :mod:`srpb_gym.sim.geometry`.
"""
