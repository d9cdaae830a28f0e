"""The world: signs, roads, props and towns, composed into one MuJoCo model."""
