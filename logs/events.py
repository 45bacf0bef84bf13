"""What the Logs app tells the rest of the platform; alerts listen (layering:
tests/test_layers.py, no domain app imports alerts)."""

from django.dispatch import Signal

# A figure of a drone's newest log drifts from its history or the fleet (logs/trends.py).
# Arguments: log, drone, check, title, detail, source (unique per log, check and basis).
# A receiver answers with a true value when it took the drift as new (an alert raised).
figure_drifted = Signal()
