"""Controllers: PD servo banks and the trip controllers built on them."""
