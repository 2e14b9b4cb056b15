"""Watching an episode while it runs: pacing to the wall clock (pacing), MuJoCo's viewer
(viewer), a Foxglove WebSocket server (foxglove_live) and a rerun stream (rerun_live).
Each is an `EpisodeObserver`; `dynabarn-run --viewer / --live` combines them."""
