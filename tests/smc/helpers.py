"""Shared helpers for the SMC tests."""

import dataclasses


def rebuild(model_class, model):
    """An instance of ``model_class`` (a subclass of ``type(model)``) with ``model``'s fields."""
    return model_class(**{field.name: getattr(model, field.name)
                          for field in dataclasses.fields(model)})
