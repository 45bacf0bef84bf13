"""Flight Controller Interface: one driver per flight-controller protocol, one interface."""
