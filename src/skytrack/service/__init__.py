"""The live service ``skytrack serve`` (issue 11 items 3 and 5): UDP ASTERIX in, reorder buffer, one tracking
task, WebSocket frames out (:mod:`skytrack.service.frames`), ``/health`` and ``/metrics``, checkpoints."""
