"""Built-in dynmodel plugins (families and data generators), registered through entry points."""
