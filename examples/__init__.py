"""Example tasks and FSAs; each task module defines ``make_task(**settings)`` and
``register(registry)`` and runs in CI with small settings."""
