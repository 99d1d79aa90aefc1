"""The data layer: one place that reads and writes the database (API and viewer use it)."""

from store.keys import KeyStore
from store.landmarks import MapRepository
from store.log import EventLog
from store.robots import RobotStore

__all__ = ["EventLog", "KeyStore", "MapRepository", "RobotStore"]
