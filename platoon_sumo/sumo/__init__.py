"""SUMO access: the libsumo backend (the only libsumo user) and offline network reading."""
