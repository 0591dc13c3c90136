/* idmap.c: the id -> index hash map (idmap.h). */
#include "common/idmap.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/random.h>

#include "common/timer.h"

/* splitmix64's finaliser of the id and the map's seed, top bits: ids that
 * are consecutive or share low bits spread, and without the seed nobody
 * can tell which ids collide. */
static uint32_t home(const ct_idmap *m, uint32_t key)
{
    uint64_t z = (uint64_t)key ^ m->seed;
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    z ^= z >> 31;
    return (uint32_t)(z >> m->shift);
}

static uint64_t new_seed(const ct_idmap *m)
{
    uint64_t s;
    if (getrandom(&s, sizeof s, GRND_NONBLOCK) == (ssize_t)sizeof s) return s;
    /* (no entropy yet, early at boot: still not known to a peer) */
    return (uint64_t)(uintptr_t)m * 0x9E3779B97F4A7C15ull ^ ct_now_us();
}

void idmap_free(ct_idmap *m)
{
    free(m->s);
    memset(m, 0, sizeof *m);
}

void idmap_clear(ct_idmap *m)
{
    for (uint32_t i = 0; i < m->cap; i++) m->s[i].val = IDMAP_NONE;
    m->n = 0;
}

uint32_t idmap_get(const ct_idmap *m, uint32_t key)
{
    if (!m->n) return IDMAP_NONE;
    for (uint32_t i = home(m, key);; i = (i + 1) & (m->cap - 1)) {
        if (m->s[i].val == IDMAP_NONE) return IDMAP_NONE;
        if (m->s[i].key == key) return m->s[i].val;
    }
}

/* Puts key into a table known to have room and not to hold it. */
static void insert(ct_idmap *m, uint32_t key, uint32_t val)
{
    uint32_t i = home(m, key);
    while (m->s[i].val != IDMAP_NONE) i = (i + 1) & (m->cap - 1);
    m->s[i] = (ct_idmap_slot){key, val};
    m->n++;
}

int idmap_put(ct_idmap *m, uint32_t key, uint32_t val, ct_error *err)
{
    if (val == IDMAP_NONE) return ct_fail(err, CT_EINVAL, "id map: index %u is the empty mark", val);
    if (m->n) {
        for (uint32_t i = home(m, key);; i = (i + 1) & (m->cap - 1)) {
            if (m->s[i].val == IDMAP_NONE) break;
            if (m->s[i].key == key) {
                m->s[i].val = val;
                return CT_OK;
            }
        }
    }
    /* at most half full: probe runs stay short */
    if (2 * (m->n + 1) > m->cap) {
        if (m->cap >= (1u << 31)) return ct_fail(err, CT_ENOMEM, "id map: more than 2^30 ids");
        uint32_t cap = m->cap ? 2 * m->cap : 64;
        ct_idmap_slot *s = malloc((size_t)cap * sizeof *s);
        if (!s) return ct_fail(err, CT_ENOMEM, "id map: out of memory for %u slots", cap);
        ct_idmap old = *m;
        if (!old.cap) m->seed = new_seed(m);
        m->s = s;
        m->cap = cap;
        m->shift = 64u - (uint32_t)__builtin_ctz(cap);
        idmap_clear(m);
        for (uint32_t i = 0; i < old.cap; i++)
            if (old.s[i].val != IDMAP_NONE) insert(m, old.s[i].key, old.s[i].val);
        free(old.s);
    }
    insert(m, key, val);
    return CT_OK;
}

void idmap_del(ct_idmap *m, uint32_t key)
{
    if (!m->n) return;
    const uint32_t mask = m->cap - 1;
    uint32_t i = home(m, key);
    for (;; i = (i + 1) & mask) {
        if (m->s[i].val == IDMAP_NONE) return;
        if (m->s[i].key == key) break;
    }
    /* Backward shift: move later entries of the run into the hole when the
     * hole lies on their probe path (between their home and them). */
    m->s[i].val = IDMAP_NONE;
    m->n--;
    for (uint32_t j = (i + 1) & mask; m->s[j].val != IDMAP_NONE; j = (j + 1) & mask) {
        uint32_t h = home(m, m->s[j].key);
        if (((j - h) & mask) >= ((j - i) & mask)) {
            m->s[i] = m->s[j];
            m->s[j].val = IDMAP_NONE;
            i = j;
        }
    }
}
