"""``fusioncut serve``: the web service (job API and browser front end) over a Dask cluster."""
from __future__ import annotations

import logging
from pathlib import Path

import typer

from fusioncut.cli._errors import friendly_errors
from fusioncut.extras import require


def register(app: typer.Typer) -> None:
    @app.command()
    @friendly_errors
    def serve(
        host: str = typer.Option("127.0.0.1", help="address to listen on (0.0.0.0: every interface)"),
        port: int = typer.Option(8000, help="TCP port"),
        workers: int = typer.Option(None, help="worker processes of the embedded Dask cluster (default: CPU count)"),
        scheduler: str = typer.Option(None, help="external Dask scheduler, e.g. tcp://10.0.0.5:8786 "
                                                  "(default: env FUSIONCUT_SCHEDULER, else an embedded cluster)"),
        data_dir: Path = typer.Option(None, help="job database and job folders (default: env FUSIONCUT_DATA_DIR, "
                                                 "else ./fusioncut-data)"),
        config: Path = typer.Option(None, help="JSON config file (default: env FUSIONCUT_CONFIG)"),
        log_level: str = typer.Option("info", help="service log level"),
    ) -> None:
        """Run the FusionCut service: HTTP API under /api, browser front end at /."""
        require("service", "fusioncut serve")
        import uvicorn

        from fusioncut.service.app import create_app
        from fusioncut.service.core import Service
        from fusioncut.service.settings import Settings

        logging.basicConfig(level=getattr(logging, log_level.upper(), logging.INFO),
                            format="%(asctime)s %(levelname)s %(name)s: %(message)s")
        if workers is not None and workers < 1:
            raise typer.BadParameter("--workers must be at least 1")
        settings = Settings.from_env(config=config, data_dir=data_dir, scheduler=scheduler, workers=workers)
        service = Service(settings)
        # Started here rather than in the web server's startup, so that a locked data folder, a bad
        # key file or an unreachable scheduler is one line of error, not a failed-startup traceback.
        try:
            service.start()
            if service.created_key_file is not None:
                typer.echo(f"no API key configured: using the key in {service.created_key_file}", err=True)
            # Event streams never end by themselves: give them a short grace on shutdown, then go.
            uvicorn.run(create_app(settings, service), host=host, port=port, log_level=log_level.lower(),
                        timeout_graceful_shutdown=3)
        finally:
            service.stop()
