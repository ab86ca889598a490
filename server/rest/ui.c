/* SPDX-License-Identifier: MIT */
/*
 * ui.c - the page mcfd serves to try it in a browser: GET / and
 * /ui/NAME, the files of web/ and three.js embedded at build time
 * (ui_assets.h). Each is answered with its media type, a strong ETag
 * (revalidated: If-None-Match gives 304), Cache-Control: no-cache (so a
 * new daemon's page is never mixed with an old one's scripts), and the
 * headers of a product page: a strict Content-Security-Policy (scripts,
 * styles, images and API calls from this origin only; no inline code, no
 * eval, no frames, no plug-ins, no form posts), nosniff, no referrer.
 *
 * The page is public, like /healthz: it holds no secret, and every API
 * call it makes carries the token the user types (the daemon's
 * --token-file rules are unchanged for the API). /ui/config.json tells
 * the page whether to ask for one ({"token_required": bool}), so that it
 * need not provoke a 401 to find out (which a browser logs as an error).
 */
#include <string.h>

#include "rest_internal.h"
#include "ui_assets.h"

#define UI_CSP "default-src 'none'; script-src 'self'; style-src 'self'; " \
               "img-src 'self' data: blob:; connect-src 'self'; "          \
               "base-uri 'none'; form-action 'none'; frame-ancestors 'none'"

#define UI_CONFIG "/ui/config.json"

int rest_ui_find(const char *path, const rest_asset **asset)
{
    size_t i;

    if (strcmp(path, UI_CONFIG) == 0) {
        *asset = NULL;
        return 1;
    }
    if (strcmp(path, "/index.html") == 0)
        path = "/";
    for (i = 0; i < rest_ui_nassets; i++)
        if (strcmp(rest_ui_assets[i].path, path) == 0) {
            *asset = &rest_ui_assets[i];
            return 1;
        }
    return 0;
}

/* Whether an If-None-Match header value lists etag (or is "*"). */
static int etag_matches(const char *inm, const char *etag)
{
    size_t n = strlen(etag);

    while (inm && *inm) {
        inm += strspn(inm, " \t,");
        if (strncmp(inm, "W/", 2) == 0) /* weak comparison (RFC 9110 13.1.2) */
            inm += 2;
        if (*inm == '*' || strncmp(inm, etag, n) == 0)
            return 1;
        inm += strcspn(inm, ",");
    }
    return 0;
}

/* The page's headers on every answer of ui.c. */
static void page_headers(struct MHD_Response *resp)
{
    MHD_add_response_header(resp, "Content-Security-Policy", UI_CSP);
    MHD_add_response_header(resp, "X-Content-Type-Options", "nosniff");
    MHD_add_response_header(resp, "Referrer-Policy", "no-referrer");
    MHD_add_response_header(resp, "Cross-Origin-Opener-Policy", "same-origin");
}

static enum MHD_Result send_config(rest_request *r, struct MHD_Connection *c)
{
    cJSON *o = cJSON_CreateObject();
    struct MHD_Response *resp;

    if (!o || !cJSON_AddBoolToObject(o, "token_required",
                                     r->door->cfg->token_len > 0)) {
        cJSON_Delete(o);
        return MHD_NO;
    }
    if (!(resp = rest_json_response(o, "application/json", 1)))
        return MHD_NO;
    MHD_add_response_header(resp, MHD_HTTP_HEADER_CACHE_CONTROL, "no-store");
    page_headers(resp);
    return rest_respond(r, c, 200, resp);
}

enum MHD_Result rest_ui_send(rest_request *r, struct MHD_Connection *c,
                             const rest_asset *a)
{
    const char *inm;
    struct MHD_Response *resp;
    int fresh;

    if (!a)
        return send_config(r, c);
    inm = MHD_lookup_connection_value(c, MHD_HEADER_KIND,
                                      MHD_HTTP_HEADER_IF_NONE_MATCH);
    fresh = etag_matches(inm, a->etag);
    resp = fresh ? rest_empty_response()
                 : MHD_create_response_from_buffer(a->len, (void *)(uintptr_t)a->data,
                                                   MHD_RESPMEM_PERSISTENT);
    if (!resp)
        return rest_respond(r, c, 500, NULL);
    MHD_add_response_header(resp, MHD_HTTP_HEADER_ETAG, a->etag);
    MHD_add_response_header(resp, MHD_HTTP_HEADER_CACHE_CONTROL, "no-cache");
    if (!fresh)
        MHD_add_response_header(resp, MHD_HTTP_HEADER_CONTENT_TYPE, a->mime);
    page_headers(resp);
    return rest_respond(r, c, fresh ? 304 : 200, resp);
}
