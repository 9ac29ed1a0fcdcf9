"""Domain plugins shipped with anytime-compose; each registers itself like a third-party plugin."""
