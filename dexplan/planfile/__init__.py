"""Plan files (``dexplan-plan/1``): the document, its schema, its verifier, its models."""

__all__ = [
    "document",
    "schema",
    "verify",
]
