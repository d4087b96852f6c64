/* Minimal Unity-compatible shim (test-only): the subset of ThrowTheSwitch Unity our tests use.
 * Used only to prove test/ compiles and passes natively where Unity cannot be downloaded;
 * PlatformIO builds the same tests against the real Unity. */
#ifndef UNITY_SHIM_H
#define UNITY_SHIM_H

#include <stdint.h>

void setUp(void);
void tearDown(void);

void UnityBegin(const char *file);
int UnityEnd(void);
void UnityDefaultTestRun(void (*func)(void), const char *name, int line);
void UnityFail(const char *msg, int line);
void UnityAssertEqualNumber(int64_t expected, int64_t actual, const char *msg, int line, int hex);
void UnityMessage(const char *msg, int line);

#define UNITY_BEGIN() UnityBegin(__FILE__)
#define UNITY_END() UnityEnd()
#define RUN_TEST(func) UnityDefaultTestRun(func, #func, __LINE__)
#define TEST_FAIL_MESSAGE(msg) UnityFail((msg), __LINE__)
#define TEST_MESSAGE(msg) UnityMessage((msg), __LINE__)
#define TEST_ASSERT_TRUE_MESSAGE(c, msg) do { if (!(c)) UnityFail((msg), __LINE__); } while (0)
#define TEST_ASSERT_TRUE(c) TEST_ASSERT_TRUE_MESSAGE(c, "Expected TRUE Was FALSE")
#define TEST_ASSERT_EQUAL_INT_MESSAGE(e, a, msg) \
    UnityAssertEqualNumber((int64_t)(e), (int64_t)(a), (msg), __LINE__, 0)
#define TEST_ASSERT_EQUAL_INT(e, a) TEST_ASSERT_EQUAL_INT_MESSAGE(e, a, 0)
#define TEST_ASSERT_EQUAL_UINT32_MESSAGE(e, a, msg) \
    UnityAssertEqualNumber((int64_t)(uint32_t)(e), (int64_t)(uint32_t)(a), (msg), __LINE__, 0)
#define TEST_ASSERT_EQUAL_UINT32(e, a) TEST_ASSERT_EQUAL_UINT32_MESSAGE(e, a, 0)
#define TEST_ASSERT_EQUAL_HEX32_MESSAGE(e, a, msg) \
    UnityAssertEqualNumber((int64_t)(uint32_t)(e), (int64_t)(uint32_t)(a), (msg), __LINE__, 1)
#define TEST_ASSERT_EQUAL_HEX32(e, a) TEST_ASSERT_EQUAL_HEX32_MESSAGE(e, a, 0)

#endif /* UNITY_SHIM_H */
