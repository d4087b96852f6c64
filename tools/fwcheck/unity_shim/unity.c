/* Minimal Unity-compatible runner (test-only): prints Unity-style results, counts failures. */
#include <setjmp.h>
#include <stdio.h>
#include "unity.h"

static const char *cur_file;
static const char *cur_test;
static int n_tests, n_fail;
static jmp_buf abort_frame;

void UnityBegin(const char *file)
{
    cur_file = file;
    n_tests = n_fail = 0;
}

void UnityMessage(const char *msg, int line) { printf("%s:%d:INFO: %s\n", cur_file, line, msg); }

void UnityFail(const char *msg, int line)
{
    printf("%s:%d:%s:FAIL: %s\n", cur_file, line, cur_test, msg ? msg : "");
    n_fail++;
    longjmp(abort_frame, 1);
}

void UnityAssertEqualNumber(int64_t e, int64_t a, const char *msg, int line, int hex)
{
    if (e == a)
        return;
    char buf[160];
    if (hex)
        snprintf(buf, sizeof buf, "Expected 0x%08llX Was 0x%08llX. %s", (unsigned long long)e,
                 (unsigned long long)a, msg ? msg : "");
    else
        snprintf(buf, sizeof buf, "Expected %lld Was %lld. %s", (long long)e, (long long)a,
                 msg ? msg : "");
    UnityFail(buf, line);
}

void UnityDefaultTestRun(void (*func)(void), const char *name, int line)
{
    cur_test = name;
    n_tests++;
    int failed_before = n_fail;
    if (setjmp(abort_frame) == 0) {
        setUp();
        func();
    }
    if (setjmp(abort_frame) == 0)
        tearDown();
    if (n_fail == failed_before)
        printf("%s:%d:%s:PASS\n", cur_file, line, name);
}

int UnityEnd(void)
{
    printf("\n-----------------------\n%d Tests %d Failures 0 Ignored\n%s\n", n_tests, n_fail,
           n_fail ? "FAIL" : "OK");
    return n_fail;
}
