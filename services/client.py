"""A small Python client of the scm-calib API (httpx), for lab scripts and notebooks.

>>> from services.client import SCMCalibClient
>>> with SCMCalibClient("http://127.0.0.1:8000", token="...") as api:     # doctest: +SKIP
...     ds = api.upload_log("examples/wf34_s020.csv")        # reads wf34_s020.json if present
...     study = api.create_study(preset="1", dataset_ids=[ds["id"]], n_samples=200)
...     api.wait(study["id"], timeout=3600)
...     post = api.samples(study["id"])                         # numpy arrays, last stage
...     print(api.summary(study["id"])["parameters"])

Every error of the server (4xx, 5xx) or of the connection raises :class:`SCMCalibError` with
the server's one-line message.
"""

from __future__ import annotations

import json
import time
import tomllib
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx
import numpy as np
from numpy.typing import NDArray

__all__ = ["SCMCalibClient", "SCMCalibError", "SCMCalibTimeoutError", "StageSamples"]

ACTIVE = ("queued", "running")


class SCMCalibError(RuntimeError):
    """A request failed: ``status_code`` is the HTTP status (None: no answer from the server)."""

    def __init__(self, message: str, status_code: int | None = None) -> None:
        super().__init__(message)
        self.status_code = status_code


class SCMCalibTimeoutError(SCMCalibError, TimeoutError):
    """:meth:`SCMCalibClient.wait` ran out of time (the study goes on)."""


@dataclass(frozen=True, eq=False)
class StageSamples:
    """The population of one stage: samples (n, d) in ``names`` order, log_likelihood and
    log_prior (n,), responses (n, k) in ``response_names`` order or None."""

    study_id: int
    stage: int
    names: list[str]
    samples: NDArray[np.float64]
    log_likelihood: NDArray[np.float64]
    log_prior: NDArray[np.float64]
    response_names: list[str] | None
    responses: NDArray[np.float64] | None

    def __len__(self) -> int:
        return int(self.samples.shape[0])

    def column(self, name: str) -> NDArray[np.float64]:
        """The samples of one parameter."""
        return self.samples[:, self.names.index(name)]


def _floats(values: Any, width: int | None = None) -> NDArray[np.float64]:
    """JSON numbers and the strings "nan", "inf", "-inf" as float64."""
    a = np.array(values, dtype=np.float64)
    if width is not None and a.size == 0:
        a = a.reshape(0, width)
    return a


class SCMCalibClient:
    """Client of one scm-calib server.

    base_url: e.g. ``http://127.0.0.1:8000``. token: the API token (needed for uploads and
    submissions; for reads when the server requires it). http_client: an ``httpx.Client`` to
    use instead of a new one (e.g. FastAPI's TestClient).
    """

    def __init__(
        self,
        base_url: str,
        token: str | None = None,
        timeout: float = 60.0,
        *,
        http_client: httpx.Client | None = None,
    ) -> None:
        self.base_url = base_url.rstrip("/")
        self.token = token
        self._own = http_client is None
        self._http = http_client or httpx.Client(timeout=timeout)
        self._timeout = timeout

    # ------------------------------------------------------------------ plumbing

    def close(self) -> None:
        if self._own:
            self._http.close()

    def __enter__(self) -> SCMCalibClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _headers(self) -> dict[str, str]:
        return {"Authorization": f"Bearer {self.token}"} if self.token else {}

    def request(self, method: str, path: str, **kwargs: Any) -> httpx.Response:
        """One request; raises :class:`SCMCalibError` unless the answer is 2xx."""
        url = self.base_url + path
        headers = {**self._headers(), **kwargs.pop("headers", {})}
        try:
            response = self._http.request(method, url, headers=headers, **kwargs)
        except httpx.HTTPError as exc:
            raise SCMCalibError(f"{method} {url}: {type(exc).__name__}: {exc}") from None
        if response.status_code >= 400:
            raise SCMCalibError(_message(response), response.status_code)
        return response

    def _json(self, method: str, path: str, **kwargs: Any) -> Any:
        return self.request(method, path, **kwargs).json()

    # ------------------------------------------------------------------ health

    def health(self) -> dict[str, Any]:
        return self._json("GET", "/health")

    def ready(self) -> dict[str, Any]:
        """The readiness report; raises SCMCalibError (503) with what failed."""
        return self._json("GET", "/health/ready")

    # ------------------------------------------------------------------ datasets

    def upload_log(
        self,
        path: str | Path,
        metadata: Mapping[str, Any] | None = None,
        *,
        offset: float | None = None,
    ) -> dict[str, Any]:
        """Upload an SWT log (or a summary file). The JSON sidecar beside it (same stem,
        ``.json``) is sent as metadata if present; ``metadata`` entries override it. Returns
        the dataset record; ``record["created"]`` is False when identical content existed."""
        path = Path(path)
        try:
            data = path.read_bytes()
        except OSError as exc:
            raise SCMCalibError(f"{path}: {exc.strerror or exc}") from None
        meta: dict[str, Any] = {}
        sidecar = path.with_suffix(".json")
        if path.suffix.lower() != ".json" and sidecar.is_file():
            try:
                doc = json.loads(sidecar.read_text(encoding="utf-8-sig"))
            except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
                raise SCMCalibError(f"sidecar {sidecar}: not valid JSON ({exc})") from None
            if not isinstance(doc, dict):
                raise SCMCalibError(f"sidecar {sidecar}: top level must be an object")
            meta.update(doc)
        meta.update(metadata or {})
        form: dict[str, str] = {}
        if meta:
            form["metadata"] = json.dumps(meta)
        if offset is not None:
            form["offset"] = repr(float(offset))
        media = "application/json" if path.suffix.lower() == ".json" else "text/csv"
        return self._json("POST", "/datasets", files={"file": (path.name, data, media)}, data=form)

    def upload_summary(
        self, summary: Mapping[str, Any] | str | Path, metadata: Mapping[str, Any] | None = None
    ) -> dict[str, Any]:
        """Upload a summary dataset: a JSON-ready dict (``name``, ``conditions``,
        ``responses`` {F, T, z, Fy: {mean, sd, unit}}, ``n_trials``) or a summary file."""
        if isinstance(summary, str | Path):
            return self.upload_log(summary, metadata)
        if metadata:
            raise SCMCalibError("metadata: put conditions and provenance in the summary dict")
        return self._json("POST", "/datasets", json=dict(summary))

    def datasets(self, limit: int = 50, offset: int = 0) -> dict[str, Any]:
        return self._json("GET", "/datasets", params={"limit": limit, "offset": offset})

    def dataset(self, dataset_id: int) -> dict[str, Any]:
        return self._json("GET", f"/datasets/{int(dataset_id)}")

    def series(self, dataset_id: int, max_points: int = 2000) -> dict[str, Any]:
        return self._json(
            "GET", f"/datasets/{int(dataset_id)}/series", params={"max_points": max_points}
        )

    # ------------------------------------------------------------------ presets

    def presets(self) -> list[dict[str, Any]]:
        return self._json("GET", "/presets")

    def preset(self, name: str) -> dict[str, Any]:
        return self._json("GET", f"/presets/{name}")

    # ------------------------------------------------------------------ studies

    def create_study(
        self,
        case: Mapping[str, Any] | str | Path | Any | None = None,
        preset: str | None = None,
        dataset_ids: Iterable[int] = (),
        **overrides: Any,
    ) -> dict[str, Any]:
        """Submit a study: ``preset`` ("1", "2a", "2b") or ``case`` (a case document dict, a
        :class:`~scm_core.calibration.CaseDefinition`, or the path of a TOML case file), the
        stored ``dataset_ids``, and overrides: seed, n_samples, moves, n_steps, max_stages,
        likelihood, name, batch_size, runs (K repeated runs with the seeds seed ... seed + K - 1:
        the answer is the first, its ``runs`` the group's ids; :meth:`pooled` on them gives
        their R-hat and a verdict). An update of a completed study: no case, ``update_of``
        its id and ``dataset_ids`` the new datasets."""
        body: dict[str, Any] = {"dataset_ids": [int(d) for d in dataset_ids]}
        if preset is not None:
            body["preset"] = str(preset)
        if case is not None:
            body["case"] = _case_document(case)
        body.update({k: v for k, v in overrides.items() if v is not None})
        return self._json("POST", "/studies", json=body)

    def studies(
        self, status: str | None = None, limit: int = 50, offset: int = 0, kind: str | None = None
    ) -> dict[str, Any]:
        """A page of studies, newest first; ``kind``: only studies of this kind (its name as
        the studies' ``kind`` gives it; default: every kind)."""
        params: dict[str, Any] = {"limit": limit, "offset": offset}
        if status:
            params["status"] = status
        if kind:
            params["kind"] = kind
        return self._json("GET", "/studies", params=params)

    def create_sensitivity(
        self,
        dataset_id: int,
        case: Mapping[str, Any] | str | Path | Any | None = None,
        preset: str | None = None,
        **options: Any,
    ) -> dict[str, Any]:
        """Submit a Morris sensitivity study under the test conditions of ``dataset_id``:
        ``preset`` or ``case`` as in :meth:`create_study`, and options r, levels, seed,
        separate_k, bounds ({name: (lower, upper)}), name, batch_size. Wait for it with
        :meth:`wait`; read it with :meth:`sensitivity`."""
        body: dict[str, Any] = {"dataset_id": int(dataset_id)}
        if preset is not None:
            body["preset"] = str(preset)
        if case is not None:
            body["case"] = _case_document(case)
        if options.get("bounds") is not None:
            options["bounds"] = {
                k: [float(v[0]), float(v[1])] for k, v in options["bounds"].items()
            }
        body.update({k: v for k, v in options.items() if v is not None})
        return self._json("POST", "/sensitivity", json=body)

    def sensitivity(self, study_id: int) -> dict[str, Any]:
        """A sensitivity study: design, progress and (once completed) its Morris ``result``."""
        return self._json("GET", f"/sensitivity/{int(study_id)}")

    def submit(self, collection: str, **body: Any) -> dict[str, Any]:
        """Submit a study to the collection of its kind, e.g.
        ``submit("predictions", study_id=3, dataset_ids=[4], draws=200)``; the body's fields
        are the kind's (see the API's documentation). Wait for it with :meth:`wait`."""
        return self._json("POST", f"/{collection.strip('/')}", json=body)

    def read(self, collection: str, study_id: int) -> dict[str, Any]:
        """A study of a kind's collection with its ``result`` once completed."""
        return self._json("GET", f"/{collection.strip('/')}/{int(study_id)}")

    def get_study(self, study_id: int) -> dict[str, Any]:
        """The study with its ``progress`` block."""
        return self._json("GET", f"/studies/{int(study_id)}")

    def cancel(self, study_id: int, reason: str | None = None) -> dict[str, Any]:
        body = {"reason": reason} if reason else None
        return self._json("POST", f"/studies/{int(study_id)}/cancel", json=body)

    def stages(self, study_id: int) -> list[dict[str, Any]]:
        return self._json("GET", f"/studies/{int(study_id)}/stages")

    def events(
        self, study_id: int, after_id: int | None = None, limit: int = 100
    ) -> list[dict[str, Any]]:
        params: dict[str, Any] = {"limit": limit}
        if after_id is not None:
            params["after_id"] = after_id
        return self._json("GET", f"/studies/{int(study_id)}/events", params=params)

    def wait(self, study_id: int, timeout: float = 3600.0, poll: float = 2.0) -> dict[str, Any]:
        """Poll until the study leaves queued/running; returns it. Raises
        :class:`SCMCalibTimeoutError` after ``timeout`` seconds (the study goes on)."""
        deadline = time.monotonic() + timeout
        while True:
            study = self.get_study(study_id)
            if study["status"] not in ACTIVE:
                return study
            left = deadline - time.monotonic()
            if left <= 0:
                p = study.get("progress") or {}
                raise SCMCalibTimeoutError(
                    f"study {study_id} still {study['status']} after {timeout:g} s "
                    f"(stage {p.get('stage')}, {p.get('evaluations_done')}/"
                    f"{p.get('evaluations_planned')} evaluations)"
                )
            time.sleep(min(poll, left))

    def watch(self, study_id: int) -> Iterator[dict[str, Any]]:
        """The study at once and after each change until it has ended, from its server-sent
        events (``GET /studies/{id}/stream``: no polling; a stream the server ends after an
        hour while the study runs is opened again)."""
        url = f"{self.base_url}/studies/{int(study_id)}/stream"
        while True:
            study: dict[str, Any] | None = None
            try:
                timeout = httpx.Timeout(self._timeout, read=None)  # a quiet stream is no error
                headers = self._headers()
                with self._http.stream("GET", url, headers=headers, timeout=timeout) as response:
                    if response.status_code >= 400:
                        response.read()
                        raise SCMCalibError(_message(response), response.status_code)
                    for line in response.iter_lines():
                        if line.startswith("data: "):
                            study = json.loads(line[6:])
                            yield study
            except httpx.HTTPError as exc:
                raise SCMCalibError(f"GET {url}: {type(exc).__name__}: {exc}") from None
            if study is None:
                raise SCMCalibError(f"GET {url}: the stream ended without an event")
            if study["status"] not in ACTIVE:
                return

    def samples(self, study_id: int, stage: int = -1, page_size: int = 5000) -> StageSamples:
        """All samples of a stage (default -1: the last finished stage) as numpy arrays."""
        offset = 0
        pages = []
        while True:
            page = self._json(
                "GET",
                f"/studies/{int(study_id)}/stages/{int(stage)}/samples",
                params={"offset": offset, "limit": page_size},
            )
            pages.append(page)
            if page["next_offset"] is None:
                break
            offset = page["next_offset"]
            stage = page["stage"]  # a fixed index from now on (-1 could move on)
        first = pages[0]
        d = len(first["names"])
        rows = [r for p in pages for r in p["samples"]]
        resp = None
        if first["responses"] is not None:
            resp = _floats([r for p in pages for r in (p["responses"] or [])])
        return StageSamples(
            study_id=int(study_id),
            stage=int(first["stage"]),
            names=list(first["names"]),
            samples=_floats(rows, d),
            log_likelihood=_floats([v for p in pages for v in p["log_likelihood"]]),
            log_prior=_floats([v for p in pages for v in p["log_prior"]]),
            response_names=first["response_names"],
            responses=resp,
        )

    def samples_csv(self, study_id: int, stage: int = -1) -> str:
        """The stage's samples as the CSV text of ``.../samples.csv``."""
        return self.request("GET", f"/studies/{int(study_id)}/stages/{int(stage)}/samples.csv").text

    def summary(self, study_id: int) -> dict[str, Any]:
        """Posterior summary of the last finished stage (mean, sd, quantiles, correlations,
        MAP, log evidence)."""
        return self._json("GET", f"/studies/{int(study_id)}/summary")

    def pooled(
        self,
        study_ids: Iterable[int],
        n_per_study: int | None = None,
        seed: int = 0,
        include_samples: bool = False,
    ) -> dict[str, Any]:
        """Pooled posterior summary of completed studies with the same parameters (Fig. 9)."""
        body: dict[str, Any] = {
            "study_ids": [int(s) for s in study_ids],
            "seed": seed,
            "include_samples": include_samples,
        }
        if n_per_study is not None:
            body["n_per_study"] = n_per_study
        return self._json("POST", "/pooled", json=body)


def _case_document(case: Any) -> dict[str, Any]:
    if isinstance(case, Mapping):
        return dict(case)
    if isinstance(case, str | Path):
        path = Path(case)
        try:
            return tomllib.loads(path.read_text(encoding="utf-8"))
        except OSError as exc:
            raise SCMCalibError(f"case file {path}: {exc.strerror or exc}") from None
        except tomllib.TOMLDecodeError as exc:
            raise SCMCalibError(f"case file {path}: not valid TOML ({exc})") from None
    if hasattr(case, "to_dict"):
        return case.to_dict()
    raise SCMCalibError(f"case: expected a dict, a CaseDefinition or a TOML path, got {case!r}")


def _message(response: httpx.Response) -> str:
    """The server's one-line ``detail``, or the start of its answer."""
    try:
        doc = response.json()
    except ValueError:
        doc = None
    if isinstance(doc, dict) and isinstance(doc.get("detail"), str):
        detail = doc["detail"]
    else:
        text = " ".join(response.text.split())[:200]
        detail = text or f"HTTP {response.status_code} {response.reason_phrase}"
    return detail
