/* SPDX-License-Identifier: MIT */
/*
 * test_docker.c - docker/compose.yaml and docker/kubernetes.yaml (and
 * their Redis-store variants, compose-redis.yaml, kubernetes-redis.yaml) parse
 * (libyaml) and agree with docker/Dockerfile and with the image `make image`
 * builds: the image name ($MCF_IMAGE, which the Makefile passes; default
 * mcfd:latest), the port, the health probe, the non-root user and the spool
 * volume. The image itself is built and run by `make image image-check`
 * (CI); this only keeps the three files from drifting apart.
 *
 * Paths are relative to the top of the tree, where `make test` runs.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <yaml.h>

#include "testlib.h"

/* ------------------------------------------------------------ YAML tree */

typedef struct {
    yaml_document_t doc[8];
    int ndoc;
} yfile;

/* Loads every document of path; fails the test when it does not parse. */
static void yload(const char *path, yfile *y)
{
    yaml_parser_t p;
    FILE *f = fopen(path, "rb");

    if (!f)
        fail_msg("cannot open %s", path);
    memset(y, 0, sizeof *y);
    yaml_parser_initialize(&p);
    yaml_parser_set_input_file(&p, f);
    for (;;) {
        yaml_document_t *d = &y->doc[y->ndoc];
        if (!yaml_parser_load(&p, d)) {
            fclose(f);
            fail_msg("%s does not parse: %s (line %lu)", path,
                     p.problem ? p.problem : "?", (unsigned long)p.problem_mark.line + 1);
        }
        if (!yaml_document_get_root_node(d)) { /* end of stream */
            yaml_document_delete(d);
            break;
        }
        if (++y->ndoc == 8)
            break;
    }
    yaml_parser_delete(&p);
    fclose(f);
}

static void yfree(yfile *y)
{
    int i;
    for (i = 0; i < y->ndoc; i++)
        yaml_document_delete(&y->doc[i]);
}

/* The value under a dotted path of mapping keys and [index]es from n, or
 * NULL: "services.mcfd.ports", "spec.containers.[0].image". */
static yaml_node_t *yget(yaml_document_t *d, yaml_node_t *n, const char *path)
{
    char key[128];
    while (n && *path) {
        size_t len = strcspn(path, ".");
        snprintf(key, sizeof key, "%.*s", (int)len, path);
        path += len + (path[len] == '.');
        if (key[0] == '[') {
            int i = atoi(key + 1);
            if (n->type != YAML_SEQUENCE_NODE ||
                i >= n->data.sequence.items.top - n->data.sequence.items.start)
                return NULL;
            n = yaml_document_get_node(d, n->data.sequence.items.start[i]);
        } else {
            yaml_node_pair_t *pr;
            yaml_node_t *found = NULL;
            if (n->type != YAML_MAPPING_NODE)
                return NULL;
            for (pr = n->data.mapping.pairs.start; pr < n->data.mapping.pairs.top; pr++) {
                yaml_node_t *k = yaml_document_get_node(d, pr->key);
                if (k->type == YAML_SCALAR_NODE && strcmp((char *)k->data.scalar.value, key) == 0)
                    found = yaml_document_get_node(d, pr->value);
            }
            n = found;
        }
    }
    return n;
}

/* The scalar at path, or the test fails naming the file and path. */
static const char *ystr(yaml_document_t *d, yaml_node_t *n, const char *path,
                        const char *file)
{
    yaml_node_t *v = yget(d, n, path);
    if (!v || v->type != YAML_SCALAR_NODE)
        fail_msg("%s: no scalar at %s", file, path);
    return (const char *)v->data.scalar.value;
}

/* Whether the sequence at path has a scalar item equal to want. */
static int yhas(yaml_document_t *d, yaml_node_t *n, const char *path, const char *want)
{
    yaml_node_t *s = yget(d, n, path);
    yaml_node_item_t *it;
    if (!s || s->type != YAML_SEQUENCE_NODE)
        return 0;
    for (it = s->data.sequence.items.start; it < s->data.sequence.items.top; it++) {
        yaml_node_t *v = yaml_document_get_node(d, *it);
        if (v->type == YAML_SCALAR_NODE && strcmp((char *)v->data.scalar.value, want) == 0)
            return 1;
    }
    return 0;
}

/* ------------------------------------------------------------ Dockerfile */

typedef struct {
    char port[16];      /* EXPOSE: the first port (HTTP) */
    char grpc_port[16]; /* EXPOSE: the second (gRPC), and ENV MCFD_GRPC_PORT */
    char volume[256];   /* VOLUME ["..."] */
    char uid[16];       /* useradd --uid */
    char user[64];      /* USER name:group */
    int probe;          /* HEALTHCHECK ... mcfd --probe */
} dockerfile;

static void read_dockerfile(dockerfile *df)
{
    char *buf, *p;
    size_t len;

    memset(df, 0, sizeof *df);
    if (tl_read_file("docker/Dockerfile", &buf, &len) != 0)
        fail_msg("cannot read docker/Dockerfile");
    if ((p = strstr(buf, "\nEXPOSE ")))
        sscanf(p + 8, "%15s %15s", df->port, df->grpc_port);
    if ((p = strstr(buf, "MCFD_GRPC_PORT=")) &&
        strncmp(p + 15, df->grpc_port, strlen(df->grpc_port)) != 0)
        fail_msg("docker/Dockerfile: MCFD_GRPC_PORT is not the EXPOSEd %s",
                 df->grpc_port);
    if ((p = strstr(buf, "\nVOLUME [\"")))
        sscanf(p + 10, "%255[^\"]", df->volume);
    if ((p = strstr(buf, "--uid ")))
        sscanf(p + 6, "%15s", df->uid);
    if ((p = strstr(buf, "\nUSER ")))
        sscanf(p + 6, "%63[^:\n]", df->user);
    p = strstr(buf, "\nHEALTHCHECK ");
    df->probe = p && strstr(p, "\"/usr/local/bin/mcfd\", \"--probe\"") != NULL;
    free(buf);
    if (!*df->port || !*df->grpc_port || !*df->volume || !*df->uid || !*df->user || !df->probe)
        fail_msg("docker/Dockerfile: EXPOSE '%s' '%s', VOLUME '%s', --uid '%s', USER '%s', "
                 "HEALTHCHECK mcfd --probe %d: one is missing", df->port, df->grpc_port,
                 df->volume,
                 df->uid, df->user, df->probe);
    assert_string_not_equal(df->uid, "0");
    assert_string_not_equal(df->user, "root");
}

static const char *image_name(void)
{
    const char *i = getenv("MCF_IMAGE");
    return i && *i ? i : "mcfd:latest";
}

/* ------------------------------------------------------------ tests */

static void test_compose(void **state)
{
    static const char *const file = "docker/compose.yaml";
    dockerfile df;
    yfile y;
    yaml_document_t *d;
    yaml_node_t *svc;
    char want[300];

    (void)state;
    read_dockerfile(&df);
    yload(file, &y);
    assert_int_equal(y.ndoc, 1);
    d = &y.doc[0];
    svc = yget(d, yaml_document_get_root_node(d), "services.mcfd");
    if (!svc)
        fail_msg("%s: no services.mcfd", file);
    /* the image `make image` builds, from this Dockerfile */
    assert_string_equal(ystr(d, svc, "image", file), image_name());
    assert_string_equal(ystr(d, svc, "build.dockerfile", file), "docker/Dockerfile");
    /* the port it exposes, published on loopback only */
    snprintf(want, sizeof want, "127.0.0.1:%s:%s", df.port, df.port);
    if (!yhas(d, svc, "ports", want))
        fail_msg("%s: ports do not publish %s", file, want);
    assert_string_equal(ystr(d, svc, "environment.MCFD_PORT", file), df.port);
    /* the gRPC door's, the same way */
    snprintf(want, sizeof want, "127.0.0.1:%s:%s", df.grpc_port, df.grpc_port);
    if (!yhas(d, svc, "ports", want))
        fail_msg("%s: ports do not publish gRPC's %s", file, want);
    assert_string_equal(ystr(d, svc, "environment.MCFD_GRPC_PORT", file),
                        df.grpc_port);
    /* the image's health check, the spool volume, a non-root user */
    if (!yhas(d, svc, "healthcheck.test", "--probe") ||
        !yhas(d, svc, "healthcheck.test", "/usr/local/bin/mcfd"))
        fail_msg("%s: healthcheck is not mcfd --probe", file);
    snprintf(want, sizeof want, "spool:%s", df.volume);
    if (!yhas(d, svc, "volumes", want))
        fail_msg("%s: no volume %s", file, want);
    snprintf(want, sizeof want, "%s:%s", df.uid, df.uid);
    assert_string_equal(ystr(d, svc, "user", file), want);
    yfree(&y);
}

static void test_kubernetes(void **state)
{
    static const char *const file = "docker/kubernetes.yaml";
    dockerfile df;
    yfile y;
    int i, deployments = 0;

    (void)state;
    read_dockerfile(&df);
    yload(file, &y);
    assert_true(y.ndoc >= 2);
    for (i = 0; i < y.ndoc; i++) {
        yaml_document_t *d = &y.doc[i];
        yaml_node_t *root = yaml_document_get_root_node(d), *pod, *c;
        if (strcmp(ystr(d, root, "kind", file), "Deployment") != 0)
            continue;
        deployments++;
        pod = yget(d, root, "spec.template.spec");
        c = yget(d, pod, "containers.[0]");
        if (!c)
            fail_msg("%s: the Deployment has no container", file);
        assert_string_equal(ystr(d, c, "image", file), image_name());
        assert_string_equal(ystr(d, c, "ports.[0].containerPort", file), df.port);
        assert_string_equal(ystr(d, c, "ports.[1].containerPort", file),
                            df.grpc_port);
        assert_string_equal(ystr(d, c, "ports.[1].name", file), "grpc");
        assert_string_equal(ystr(d, pod, "securityContext.runAsUser", file), df.uid);
        assert_string_equal(ystr(d, pod, "securityContext.runAsNonRoot", file), "true");
        assert_string_equal(ystr(d, c, "livenessProbe.httpGet.path", file), "/healthz");
        assert_string_equal(ystr(d, c, "readinessProbe.httpGet.path", file), "/readyz");
        assert_string_equal(ystr(d, c, "volumeMounts.[0].name", file), "spool");
        assert_string_equal(ystr(d, c, "volumeMounts.[0].mountPath", file), df.volume);
    }
    assert_int_equal(deployments, 1);
    yfree(&y);
}

/* The Redis deployments (issue 22): the store URL names the Redis service,
 * Redis keeps its append-only file with appendfsync always on a volume,
 * the password reaches mcfd as a file (never an argument), one mcfd. */
static void check_redis_command(const char *cmd, const char *file)
{
    if (!strstr(cmd, "--appendonly yes") || !strstr(cmd, "--appendfsync always") ||
        !strstr(cmd, "--dir /data") || !strstr(cmd, "--requirepass \"$"))
        fail_msg("%s: redis-server is not run with its AOF (appendfsync always) in /data "
                 "and the password from the secret: %s", file, cmd);
}

static void test_redis_deploy(void **state)
{
    static const char *const cf = "docker/compose-redis.yaml",
                             *const kf = "docker/kubernetes-redis.yaml";
    yfile y;
    yaml_document_t *d;
    yaml_node_t *root, *svc, *redis;
    int i, seen = 0;

    (void)state;
    yload(cf, &y);
    d = &y.doc[0];
    root = yaml_document_get_root_node(d);
    svc = yget(d, root, "services.mcfd");
    redis = yget(d, root, "services.redis");
    if (!svc || !redis)
        fail_msg("%s: no services.mcfd and services.redis", cf);
    assert_string_equal(ystr(d, svc, "image", cf), image_name());
    assert_string_equal(ystr(d, svc, "environment.MCFD_STORE", cf), "redis://redis:6379");
    assert_string_equal(ystr(d, svc, "environment.MCFD_STORE_PASSWORD_FILE", cf),
                        "/run/secrets/redis_password");
    if (!yhas(d, svc, "secrets", "redis_password") || !yhas(d, redis, "secrets", "redis_password"))
        fail_msg("%s: the password secret is not given to both", cf);
    check_redis_command(ystr(d, redis, "command.[2]", cf), cf);
    if (!yhas(d, redis, "volumes", "redis:/data"))
        fail_msg("%s: redis keeps /data on no volume", cf);
    assert_string_equal(ystr(d, svc, "deploy.replicas", cf), "2");
    /* replicas take host ports from a range, one each */
    assert_string_equal(ystr(d, svc, "ports.[0]", cf), "127.0.0.1:8080-8081:8080");
    yfree(&y);

    yload(kf, &y);
    for (i = 0; i < y.ndoc; i++) {
        yaml_node_t *pod, *c;
        const char *kind;
        d = &y.doc[i];
        root = yaml_document_get_root_node(d);
        kind = ystr(d, root, "kind", kf);
        pod = yget(d, root, "spec.template.spec");
        c = yget(d, pod, "containers.[0]");
        if (strcmp(kind, "StatefulSet") == 0) {
            seen |= 1;
            assert_string_equal(ystr(d, root, "metadata.name", kf), "mcfd-redis");
            check_redis_command(ystr(d, c, "args.[0]", kf), kf);
            assert_string_equal(ystr(d, c, "volumeMounts.[0].mountPath", kf), "/data");
            assert_string_equal(ystr(d, root, "spec.volumeClaimTemplates.[0].metadata.name", kf),
                                ystr(d, c, "volumeMounts.[0].name", kf));
        } else if (strcmp(kind, "Deployment") == 0) {
            seen |= 2;
            assert_string_equal(ystr(d, c, "image", kf), image_name());
            if (atoi(ystr(d, root, "spec.replicas", kf)) < 2)
                fail_msg("%s: the Deployment runs fewer than 2 replicas", kf);
            assert_string_equal(ystr(d, root, "spec.strategy.type", kf), "RollingUpdate");
            assert_string_equal(ystr(d, root, "spec.strategy.rollingUpdate.maxUnavailable", kf),
                                "0");
            assert_string_equal(ystr(d, c, "env.[3].name", kf), "MCFD_STORE");
            assert_string_equal(ystr(d, c, "env.[3].value", kf), "redis://mcfd-redis:6379");
            assert_string_equal(ystr(d, c, "env.[4].name", kf), "MCFD_STORE_PASSWORD_FILE");
            assert_string_equal(ystr(d, c, "readinessProbe.httpGet.path", kf), "/readyz");
            assert_string_equal(ystr(d, c, "livenessProbe.httpGet.path", kf), "/healthz");
        } else if (strcmp(kind, "HorizontalPodAutoscaler") == 0) {
            seen |= 4;
            assert_string_equal(ystr(d, root, "apiVersion", kf), "autoscaling/v2");
            assert_string_equal(ystr(d, root, "spec.scaleTargetRef.kind", kf), "Deployment");
            assert_string_equal(ystr(d, root, "spec.scaleTargetRef.name", kf), "mcfd");
            if (atoi(ystr(d, root, "spec.minReplicas", kf)) < 2)
                fail_msg("%s: the autoscaler may go below 2 replicas", kf);
            assert_string_equal(ystr(d, root, "spec.metrics.[0].resource.name", kf), "cpu");
        }
    }
    assert_int_equal(seen, 7);
    yfree(&y);
}

/* The licence and the third-party notice travel in the image: the
 * runtime stage copies LICENSE and docker/THIRD-PARTY-NOTICES to
 * /usr/share/doc/mcfd and appends the package list (docker/notices.sh;
 * `make image-check` checks that list against the image), every package
 * the runtime stage installs is named in the notice's table, and three.js,
 * which mcfd embeds for its page, is named with its licence shipped. */
static void test_notices(void **state)
{
    char *df, *notice, *lic, *at, *end;
    size_t len;
    int named = 0;

    (void)state;
    if (tl_read_file("docker/Dockerfile", &df, &len) != 0 ||
        tl_read_file("docker/THIRD-PARTY-NOTICES", &notice, &len) != 0 ||
        tl_read_file("LICENSE", &lic, &len) != 0)
        fail_msg("cannot read docker/Dockerfile, docker/THIRD-PARTY-NOTICES or LICENSE");
    assert_int_equal(strncmp(lic, "MIT License\n", 12), 0);
    assert_non_null(strstr(df, "COPY LICENSE docker/THIRD-PARTY-NOTICES /usr/share/doc/mcfd/"));
    assert_non_null(strstr(df, "sh /tmp/notices.sh /usr/share/doc/mcfd/THIRD-PARTY-NOTICES"));
    /* three.js is embedded in mcfd (the page): named, its licence shipped */
    assert_non_null(strstr(notice, "three.js"));
    assert_non_null(strstr(df, "COPY node_modules/three/LICENSE /usr/share/doc/mcfd/three.js-LICENSE"));
    /* the runtime stage's package list: from its --no-install-recommends
     * to the `&&` that ends it */
    at = strstr(df, "AS runtime");
    at = at ? strstr(at, "--no-install-recommends") : NULL;
    end = at ? strstr(at, "&&") : NULL;
    if (!at || !end)
        fail_msg("docker/Dockerfile: no apt-get install in the runtime stage");
    at += strlen("--no-install-recommends");
    while (at < end) {
        char pkg[64], word[70];
        size_t n = strspn(at, " \t\\\n");
        at += n;
        n = strcspn(at, " \t\\\n");
        if (at >= end || n == 0)
            break;
        if (n >= sizeof pkg)
            fail_msg("docker/Dockerfile: '%.40s...' is not a package name", at);
        memcpy(pkg, at, n);
        pkg[n] = '\0';
        at += n;
        /* named as a word of the table: "(libmicrohttpd12)", "libgrpc29, " */
        snprintf(word, sizeof word, "%s)", pkg);
        if (!strstr(notice, word)) {
            snprintf(word, sizeof word, "%s,", pkg);
            if (!strstr(notice, word))
                fail_msg("docker/THIRD-PARTY-NOTICES does not name %s, which the image installs",
                         pkg);
        }
        named++;
    }
    assert_true(named >= 10);
    free(df);
    free(notice);
    free(lic);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_compose),
        cmocka_unit_test(test_kubernetes),
        cmocka_unit_test(test_redis_deploy),
        cmocka_unit_test(test_notices),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
