"""Process-wide runtime settings shared by the command-line programs and sweep workers."""
