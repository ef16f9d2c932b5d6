"""Placeholder: filled in by the bat family implementation."""
