"""Sensor models of the lander (core, plain numpy): what the flight software sees of the truth.

One module per sensor, each with its typed parameter table (:mod:`.params`) and its measurement
model: :mod:`.imu` (gyro and accelerometer), :mod:`.star_tracker`, :mod:`.altimeter` (radar slant
range), :mod:`.doppler` (velocity over the ground), :mod:`.ground_fix` (radiometric position and
velocity for orbit and entry). :mod:`.suite` parses a scene's ``sensors:`` section and samples the
sensors at their rates from a seed; :mod:`.truth` reads the truth (with the specific force) from a
simulation. docs/estimation.md is the user guide.
"""
