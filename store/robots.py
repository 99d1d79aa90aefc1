"""Robot configurations in the database (name, source, camera calibration, wheel base)."""

from __future__ import annotations

import builtins

from sqlalchemy import Engine
from sqlmodel import Session, col, select

from store.errors import NotFoundError
from store.models import Robot, RobotCreate, RobotPublic, utcnow


class RobotStore:
    """The robots the site runs; the live site starts one localizer per record."""

    def __init__(self, engine: Engine) -> None:
        self.engine = engine

    def list(self) -> builtins.list[RobotPublic]:
        with Session(self.engine) as s:
            rows = s.exec(select(Robot).order_by(col(Robot.name)))
            return [RobotPublic.model_validate(r, from_attributes=True) for r in rows]

    def get(self, name: str) -> RobotPublic:
        with Session(self.engine) as s:
            row = s.get(Robot, name)
            if row is None:
                raise NotFoundError(f"robot {name!r} does not exist")
            return RobotPublic.model_validate(row, from_attributes=True)

    def upsert(self, data: RobotCreate) -> RobotPublic:
        """Create the robot or replace its configuration."""
        with Session(self.engine) as s:
            row = s.get(Robot, data.name)
            if row is None:
                row = Robot.model_validate(data.model_dump())
            else:
                for key, value in data.model_dump(exclude={"name"}).items():
                    setattr(row, key, value)
                row.updated_at = utcnow()
            s.add(row)
            s.commit()
            s.refresh(row)
            return RobotPublic.model_validate(row, from_attributes=True)

    def delete(self, name: str) -> None:
        with Session(self.engine) as s:
            row = s.get(Robot, name)
            if row is None:
                raise NotFoundError(f"robot {name!r} does not exist")
            s.delete(row)
            s.commit()
