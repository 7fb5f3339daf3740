"""Control of the lander: design library (:mod:`.design`) and controller plug-ins (:mod:`.controllers`).

Plain Python; imports no rclpy. ``import control`` (python-control, ~1.5 s) happens only
inside the design functions that need it, never at import time.
"""
