"""The differential-drive robot, its arm variant and its worlds (soccer field, kitchen)."""

# The robot's facts that the worlds, the controllers and the skills compute with (the URDF,
# ``diffdrive.urdf``, has the same numbers).
WHEEL_RADIUS = 0.0975  # [m]
TRACK = 0.33  # distance between the wheel centres [m]
MAX_WHEEL_SPEED = 12.0  # [rad/s], the URDF velocity limit
MAX_FORWARD_SPEED = MAX_WHEEL_SPEED * WHEEL_RADIUS  # [m/s], both wheels at their limit
