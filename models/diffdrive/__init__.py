"""The differential-drive robot, its arm variant and its worlds (soccer field, kitchen)."""
