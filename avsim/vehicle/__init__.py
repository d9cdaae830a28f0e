"""The ego vehicle: named physics readouts and actuation (drive, brakes, steering, resistances)."""
