"""The home page at `/`: what runs here and where to go (viewer, API docs, health).

No key is needed to see it (it shows what `/healthz` shows); every page it links to that
reads the site asks for a key. Plain HTML without outside assets: plant networks are offline.
"""

from __future__ import annotations

from html import escape

from fastapi import APIRouter, Request
from fastapi.responses import HTMLResponse

from server.health import site_health

PAGE = """<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>irloc</title>
<meta name="viewport" content="width=device-width, initial-scale=1">
<style>
body {{ font-family: system-ui, sans-serif; max-width: 46rem; margin: 2rem auto;
        padding: 0 1rem; color: #222; line-height: 1.45; }}
h1 {{ margin-bottom: 0.2rem; }} .sub {{ color: #666; margin-top: 0; }}
ul {{ padding-left: 1.2rem; }} li {{ margin: 0.35rem 0; }}
code {{ background: #f2f2f2; padding: 0 0.25rem; border-radius: 3px; }}
form {{ margin: 0.4rem 0 0 0; }} input {{ font: inherit; width: 22rem; max-width: 70%; }}
.status {{ background: #f5f8f5; border: 1px solid #cdc; padding: 0.5rem 0.8rem; }}
</style></head><body>
<h1>irloc</h1>
<p class="sub">Indoor localization with infrared ceiling landmarks</p>
<p class="status">{status}</p>
<ul>
<li><a href="/viewer/"><b>3D viewer</b></a> (monitoring and commissioning) &mdash; needs an
API key: open <code>/viewer/?token=KEY</code> or paste it here:
<form action="/viewer/" method="get"><input name="token" type="password"
placeholder="API key" autocomplete="off"> <button type="submit">Open the viewer</button></form>
</li>
<li><a href="/docs"><b>API documentation</b></a> (Swagger UI, try requests with
<i>Authorize</i>) &middot; <a href="/redoc">ReDoc</a> &middot;
<a href="/openapi.json">openapi.json</a></li>
<li><a href="/healthz">Health</a> (no key) &middot; Prometheus metrics at
<code>/api/v1/metrics</code> (key)</li>
</ul>
<p>An API key comes from <code>irloc keys create --role viewer|operator|admin --data-dir
{data_dir}</code> on this machine; the first admin key was printed once when the site was
first started.</p>
</body></html>
"""


def landing_router() -> APIRouter:
    """`GET /`: the home page (left out of the API schema)."""
    router = APIRouter(include_in_schema=False)

    @router.get("/")
    async def home(request: Request) -> HTMLResponse:
        services = getattr(request.app.state, "services", None)
        if services is None:
            status, data_dir = "starting", "DIR"
        else:
            h = site_health(services)
            status = f"running: {h.robots} robots, {h.landmarks} landmarks, radio {h.radio}"
            data_dir = str(services.settings.data_dir)
        return HTMLResponse(PAGE.format(status=escape(status), data_dir=escape(data_dir)))

    return router
