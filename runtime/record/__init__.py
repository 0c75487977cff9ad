"""Recording a daemon to MCAP, reading and replaying it, and what is drawn and scored from it:
the live view, scene pictures, the demo's summary and scorecard."""
