#include <embree3/rtcore.h>
#include <stdio.h>
#include <stddef.h>
#define S(T) printf("size %s %zu align %zu\n", #T, sizeof(struct T), _Alignof(struct T))
#define O(T,f) printf("  off %s.%s %zu\n", #T, #f, offsetof(struct T, f))
int main(void){
  S(RTCRay); O(RTCRay,org_x);O(RTCRay,org_y);O(RTCRay,org_z);O(RTCRay,tnear);O(RTCRay,dir_x);O(RTCRay,dir_y);O(RTCRay,dir_z);O(RTCRay,time);O(RTCRay,tfar);O(RTCRay,mask);O(RTCRay,id);O(RTCRay,flags);
  S(RTCHit); O(RTCHit,Ng_x);O(RTCHit,Ng_y);O(RTCHit,Ng_z);O(RTCHit,u);O(RTCHit,v);O(RTCHit,primID);O(RTCHit,geomID);O(RTCHit,instID);
  S(RTCRayHit); O(RTCRayHit,ray); O(RTCRayHit,hit);
  S(RTCIntersectContext); O(RTCIntersectContext,flags);O(RTCIntersectContext,filter);O(RTCIntersectContext,instID);
  printf("enum size %zu\n", sizeof(enum RTCIntersectContextFlags));
  printf("FLOAT3 0x%x UINT3 0x%x\n", RTC_FORMAT_FLOAT3, RTC_FORMAT_UINT3);
  printf("RTC_MAX_INSTANCE_LEVEL_COUNT %d RTC_MIN_WIDTH %d\n", RTC_MAX_INSTANCE_LEVEL_COUNT, RTC_MIN_WIDTH);
  return 0;
}
