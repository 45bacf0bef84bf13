"""Airspace happenings other apps react to, without airspace importing them."""

from django.dispatch import Signal

# Sent by the live watch after it held a drone predicted to lose separation. Arguments:
# drone (the one held), other (the one it kept flying), in_s (seconds until the predicted
# loss), horizontal_m and vertical_m (apart then), action (what was sent).
separation_lost = Signal()
