"""magna_gs: the ground station: mission JSON -> state machine, agent spawning, commands, recording."""
