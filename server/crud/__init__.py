"""The data layer: one place that reads and writes the database (API and viewer use it)."""

from server.crud.keys import KeyStore
from server.crud.landmarks import MapRepository
from server.crud.log import EventLog
from server.crud.robots import RobotStore

__all__ = ["EventLog", "KeyStore", "MapRepository", "RobotStore"]
