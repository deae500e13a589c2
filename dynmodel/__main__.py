"""``python -m dynmodel``: the ``dynmodel`` command (where the console script is not on the PATH)."""

from .launch import main

if __name__ == "__main__":
    main()
