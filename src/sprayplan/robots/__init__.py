"""Robot models (standard D-H chains as data), forward and inverse kinematics, the nine-axis gantry + UR5."""
