"""The navigation task: anytime vision (`vision`), plan execution and plan quality on the true
map (`execution`), the task, the monitor's environment model and what a run reports (`model`),
the frame program (`frame_program`: sense, then plan, compiled and traced), the frame loop
(`frames`: `run_task`), and the pictures of a run's frames (`frame_figures`)."""
