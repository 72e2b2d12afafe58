// The server's API. The browser sends the session's cookie with every call: the server set
// it (HTTP-only, same-site) when the page was opened by the one-time address recon annotate
// printed, so no script here ever sees the session's key.

export class ApiError extends Error {
  constructor(status, body) {
    super(body?.error ?? `HTTP ${status}`);
    this.status = status;
    this.where = body?.where ?? null;
    this.fix = body?.fix ?? null;
  }
}

export class Api {
  async _fetch(path, options = {}) {
    const headers = { ...(options.headers ?? {}) };
    const response = await fetch(path, { ...options, headers, cache: "no-store", credentials: "same-origin" });
    if (!response.ok) {
      let body = null;
      try { body = await response.json(); } catch { /* not JSON */ }
      throw new ApiError(response.status, body);
    }
    return response;
  }

  async get(path) { return (await this._fetch(path)).json(); }

  async send(method, path, body) {
    const response = await this._fetch(path, {
      method, body: JSON.stringify(body), headers: { "Content-Type": "application/json" },
    });
    return response.json();
  }

  async bytes(path) { return (await this._fetch(path)).arrayBuffer(); }

  /** An object URL for an image the server holds (images cannot send headers). */
  async objectUrl(path) { return URL.createObjectURL(await (await this._fetch(path)).blob()); }
}
