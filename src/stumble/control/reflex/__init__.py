"""The neuromuscular reflex controller (seed 003): recorded walk, receptors, network."""
