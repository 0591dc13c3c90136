#include "common/log.h"
#include "common/timer.h"

#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <unistd.h>

static ct_log_level g_level = CT_LOG_INFO;
static pthread_mutex_t g_lock = PTHREAD_MUTEX_INITIALIZER;
static double g_last_progress = -1.0;
static int g_progress_open = 0;

static const char *level_name(ct_log_level l)
{
    switch (l) {
    case CT_LOG_ERROR: return "error";
    case CT_LOG_WARN: return "warn";
    case CT_LOG_INFO: return "info";
    default: return "debug";
    }
}

void ct_log_set_level(ct_log_level level) { g_level = level; }
ct_log_level ct_log_get_level(void) { return g_level; }

void ct_log(ct_log_level level, const char *component, const char *fmt, ...)
{
    if (level > g_level) return;
    char msg[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    pthread_mutex_lock(&g_lock);
    if (g_progress_open) { fputc('\n', stderr); g_progress_open = 0; }
    fprintf(stderr, "%s %s: %s\n", level_name(level), component, msg);
    pthread_mutex_unlock(&g_lock);
}

void ct_progress(const char *component, double fraction, int done, const char *fmt, ...)
{
    if (g_level < CT_LOG_INFO) return;
    double now = ct_now();
    int tty = isatty(STDERR_FILENO);
    pthread_mutex_lock(&g_lock);
    int due = done || g_last_progress < 0 || now - g_last_progress >= (tty ? 0.1 : 1.0);
    if (due) {
        char msg[512];
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(msg, sizeof msg, fmt, ap);
        va_end(ap);
        if (tty) {
            fprintf(stderr, "\rprogress %s: %5.1f%% %s\033[K", component, 100.0 * fraction, msg);
            g_progress_open = !done;
            if (done) fputc('\n', stderr);
        } else {
            fprintf(stderr, "progress %s: %5.1f%% %s\n", component, 100.0 * fraction, msg);
        }
        fflush(stderr);
        g_last_progress = done ? -1.0 : now;
    }
    pthread_mutex_unlock(&g_lock);
}
