/* log.h: one line per event on stderr, "level component: message".
 * The level is process-wide (--quiet / --verbose set it once in main). */
#ifndef CT_LOG_H
#define CT_LOG_H

typedef enum ct_log_level {
    CT_LOG_ERROR = 0,
    CT_LOG_WARN  = 1,
    CT_LOG_INFO  = 2,
    CT_LOG_DEBUG = 3
} ct_log_level;

/* Sets the most verbose level that is printed (default CT_LOG_INFO). */
void ct_log_set_level(ct_log_level level);

/* Current level. */
ct_log_level ct_log_get_level(void);

/* Prints "level component: message" when level is enabled. Thread-safe. */
void ct_log(ct_log_level level, const char *component, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

/* A progress line that rewrites itself on a terminal ("\r"), or is printed at
 * most once a second otherwise; done=1 ends it with a newline. */
void ct_progress(const char *component, double fraction, int done, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));

#define ct_error_log(comp, ...) ct_log(CT_LOG_ERROR, comp, __VA_ARGS__)
#define ct_warn(comp, ...)      ct_log(CT_LOG_WARN, comp, __VA_ARGS__)
#define ct_info(comp, ...)      ct_log(CT_LOG_INFO, comp, __VA_ARGS__)
#define ct_debug(comp, ...)     ct_log(CT_LOG_DEBUG, comp, __VA_ARGS__)

#endif
