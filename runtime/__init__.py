"""What the ground's long-running processes, the development run, the benchmarks and the
load drones share, and drones never run: supervising child processes (`processes`),
retrying a connection with backoff (`retry`), MQTT packets for the hand-written clients
(`mqttwire`), and the stop SIGTERM and SIGINT ask of a main loop (`stopsignal`). Plain
Python, no Django."""
