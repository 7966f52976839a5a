"""Systems from the papers, one module each (installed as ``nsm_continuation.problems``)."""
