"""The HTTP API in routers by concern; :func:`fusioncut.service.app.create_app` assembles them.

* :mod:`~fusioncut.service.routes.access` — the API key, a job's lookup and status, what the routes
  of one application share (:class:`~fusioncut.service.routes.access.Api`);
* :mod:`~fusioncut.service.routes.jobs` — submit, list, status, cancel, delete;
* :mod:`~fusioncut.service.routes.events` — server-sent events of one job or of every job of a key;
* :mod:`~fusioncut.service.routes.results` — result files and downloads, summary, one CL, plots;
* :mod:`~fusioncut.service.routes.scenes` — the 3D view: the whole job, and the workpiece after a CL;
* :mod:`~fusioncut.service.routes.front` — service info, the browser front end and the API pages.

Routers are module-level; what belongs to one application (its service, caches, open streams) is in
``app.state`` and reaches a route through a dependency, so two applications in one process share
nothing but the limits on CPU-heavy work.
"""
