"""Placeholder: filled in by the central_force family implementation."""
