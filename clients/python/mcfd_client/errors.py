# SPDX-License-Identifier: MIT
"""mcfd_client.errors - the typed errors and warnings of the client.

Every failure the daemon reports becomes an MCFDError subclass chosen by the
daemon's symbolic `code` (REST: the problem document's `code`; gRPC: the
trailing metadata `mcf-code`), which the exception carries with the HTTP
status or gRPC status name, the daemon's `detail` and the job ID when there
is one. Codes are openapi.yaml's (Problem.code) and mcfd.proto's.
"""


class MCFDError(Exception):
    """A request the daemon refused or a job that failed.

    code: the daemon's code (EINVAL, ELIMIT, EMESH, EBUSY, ...; None when
    the daemon was not reached); status: the HTTP status (int) or the gRPC
    status name (str); detail: the daemon's message; job: the job ID or
    None; retry_after: seconds the daemon asked to wait, or None."""

    def __init__(self, detail, code=None, status=None, job=None, retry_after=None):
        super().__init__("%s%s" % ("%s: " % code if code else "", detail))
        self.detail = detail
        self.code = code
        self.status = status
        self.job = job
        self.retry_after = retry_after


class InvalidParameter(MCFDError):
    """EINVAL: a parameter unknown, of the wrong type or out of range (the
    detail names it and what it accepts), or a malformed request."""


class MeshError(MCFDError):
    """The mesh: not a mesh (EFORMAT), does not decode (EDECODE), cannot be
    smoothed (EMESH, ENOTPOSDEF, ENUMERIC, ENOCONV)."""


class LimitExceeded(MCFDError):
    """ELIMIT or ETIMEOUT: over one of the daemon's limits (size, vertices,
    work, steps, memory, time); the detail names it."""


class Busy(MCFDError):
    """The daemon cannot take the job now (EBUSY, ESPOOLFULL, EDRAINING,
    ENOMEM), raised once the retries are spent."""


class Unauthorized(MCFDError):
    """EAUTH: the daemon has a token and the request's was missing or wrong."""


class NotFound(MCFDError):
    """ENOTFOUND: no such job or route."""


class Canceled(MCFDError):
    """ECANCELED: the job was canceled."""


class NotReady(MCFDError):
    """ENOTREADY: the job has not finished yet; ENORESULT: it finished
    without a result (failed, canceled, or no fields were asked for)."""


class ServerError(MCFDError):
    """The daemon failed (EIO, ESPOOL, ...), or a code this client does not know."""


class Unreachable(MCFDError):
    """The daemon could not be reached (connection refused, DNS, TLS)."""


_BY_CODE = {
    "EINVAL": InvalidParameter,
    "EFORMAT": MeshError, "EDECODE": MeshError, "EMESH": MeshError,
    "ENOTPOSDEF": MeshError, "ENUMERIC": MeshError, "ENOCONV": MeshError,
    "ELIMIT": LimitExceeded, "ETIMEOUT": LimitExceeded,
    "EBUSY": Busy, "ESPOOLFULL": Busy, "EDRAINING": Busy, "ENOMEM": Busy,
    "EAUTH": Unauthorized,
    "ENOTFOUND": NotFound,
    "ECANCELED": Canceled,
    "ENOTREADY": NotReady, "ENORESULT": NotReady,
}


def error_for(code, detail, **kw):
    """The exception of the daemon's code."""
    return _BY_CODE.get(code, ServerError)(detail, code=code, **kw)


class SmoothingWarning(UserWarning):
    """The daemon smoothed the mesh but warns about the result: `name` is
    one of folds, edge_collapse, area_loss, little_smoothing (the metrics'
    `warnings`). Issued with warnings.warn; turn them into exceptions with
    warnings.simplefilter("error", mcfd_client.SmoothingWarning)."""

    def __init__(self, name, job=None):
        super().__init__("mcfd warns about the result: %s%s" % (
            name, " (job %s)" % job if job else ""))
        self.name = name
        self.job = job
