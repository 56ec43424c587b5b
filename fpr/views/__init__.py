"""The views layer: the thesis' figures (matplotlib) and the meshcat scene. Views read plans and logs; nothing
below imports them.
"""
