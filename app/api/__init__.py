"""The REST API under ``/api``: one router module per resource, plus models, errors and dependencies."""
