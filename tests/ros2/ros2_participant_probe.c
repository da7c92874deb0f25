/* ros2_participant_probe DOMAIN GUID_HEX: prints the USER_DATA of the DDS participant whose
 * GUID is GUID_HEX (32 hex digits), as DDS discovery (the DCPSParticipant built-in topic) shows
 * it to any participant of DOMAIN; exit 1 when no such participant shows up in 10 s. Plain
 * Cyclone C API: the ros2 transport's tests (test_ros2_topics.py) check with it what
 * rmw_cyclonedds reads (PyPI's cyclonedds 11.0.1 crashes reading built-in topics). Cyclone's
 * settings come from CYCLONEDDS_URI (ctest: config/dds/loopback.xml). */
#include <dds/dds.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int matches(const dds_guid_t* guid, const char* hex) {
  char text[33];
  for (int i = 0; i < 16; i++) snprintf(text + 2 * i, 3, "%02x", guid->v[i]);
  return strcmp(text, hex) == 0;
}

int main(int argc, char** argv) {
  if (argc != 3 || strlen(argv[2]) != 32) {
    fprintf(stderr, "usage: %s DOMAIN GUID_HEX\n", argv[0]);
    return 2;
  }
  const dds_entity_t participant =
      dds_create_participant((dds_domainid_t)atoi(argv[1]), NULL, NULL);
  if (participant < 0) {
    fprintf(stderr, "no participant: %s\n", dds_strretcode(participant));
    return 2;
  }
  const dds_entity_t reader =
      dds_create_reader(participant, DDS_BUILTIN_TOPIC_DCPSPARTICIPANT, NULL, NULL);
  for (int tries = 0; tries < 100; tries++) { /* 10 s */
    void* samples[16] = {0};
    dds_sample_info_t infos[16];
    const int n = dds_take(reader, samples, infos, 16, 16);
    for (int i = 0; i < n; i++) {
      const dds_builtintopic_participant_t* p = samples[i];
      void* data = NULL;
      size_t size = 0;
      if (!infos[i].valid_data || !matches(&p->key, argv[2])) continue;
      if (dds_qget_userdata(p->qos, &data, &size) && size > 0) {
        /* the last announcement counts: USER_DATA may be set just after creation */
        printf("%.*s\n", (int)size, (const char*)data);
        fflush(stdout);
        dds_free(data);
        dds_delete(participant);
        return 0;
      }
      dds_free(data);
    }
    if (n > 0) dds_return_loan(reader, samples, n);
    dds_sleepfor(DDS_MSECS(100));
  }
  fprintf(stderr, "participant %s: no USER_DATA seen in 10 s\n", argv[2]);
  dds_delete(participant);
  return 1;
}
