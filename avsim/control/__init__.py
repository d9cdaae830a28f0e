"""Control: the cruise and lane-keeping controllers and the braking policies."""
