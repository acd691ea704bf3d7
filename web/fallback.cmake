# Writes the one-page fallback of web-dist/ when the front end cannot be bundled (no node/npm).
file(MAKE_DIRECTORY ${OUT})
file(GLOB old ${OUT}/*)
if(old)
  file(REMOVE ${old})
endif()
file(WRITE ${OUT}/index.html [=[<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>occmap</title></head>
<body><h1>occmap serve</h1>
<p>This binary was built without its web front end (node and npm were not found). The JSON API
works: <a href="api/state">api/state</a>, <a href="api/site">api/site</a>. Run
<code>scripts/install-deps.sh</code> and rebuild for the live view and the setup pages.</p>
</body></html>
]=])
file(WRITE ${OUT}/manifest.txt "index.html\n")
