"""Placeholder: filled in by the whale family implementation."""
