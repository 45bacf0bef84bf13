"""Third-person view from past images (SPIRIT, [Sugimoto 2005]), free of Django and MQTT.

``selection.PastView`` is the entry point: feed it camera frames and poses, it returns
plain dicts for the page. The other modules are its parts: ``geometry`` (quaternions),
``evaluation`` (the frame scoring functions), ``buffer`` (stored frames) and
``tracking`` (lost/found detection).
"""
