"""``pr2.env``: the original platform's environment."""

from pr2.env.env import Env

__all__ = ["Env"]
