"""The on-robot agent (`irloc agent`): the localizer on the robot, talking MQTT to the site.
Imports `fleet`, `localizer` and (for `--sim`) `sim`; never `server` or `web`."""
