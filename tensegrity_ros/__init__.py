"""tensegrity_ros: planar tensegrity mechanism (Wenger & Chablat) for a robotic bird neck."""
