"""Operator web interface (seed section 3.6 / SPEC section 8): plan, operate, watch.

A FastAPI + uvicorn server in a background thread, a WebSocket hub that streams telemetry from
the bus and forwards validated control messages of the one authenticated pilot, and a
dependency-free front end (canvas map in local metres over offline tiles from the boat's cache,
canvas plots, alerts) in ``static/``; optional TLS (``tls.py``), admission that keeps the pilot's
seat reachable (``admission.py``).

Attach to a stack with ``lotsen.stack.web.add_web(stack)``.
"""
