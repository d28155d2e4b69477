//! The enclave's credentials, checked before the secure participant is made (cargo
//! feature `security`): a node with a bad certificate, key, permissions or governance
//! stops at start-up with one line naming the file and the reason, instead of running
//! with a participant no peer will match (or that rustdds refuses later, less clearly).
//!
//! As DDS Security's built-in plugins read them (`ros2 security`'s file names):
//!
//! - `identity_ca.cert.pem`, `permissions_ca.cert.pem`: PEM certificates, valid now;
//! - `cert.pem`: a PEM certificate, valid now, signed by the identity CA;
//! - `key.pem`: a PEM private key (not password-protected), the key of `cert.pem`;
//! - `governance.p7s`, `permissions.p7s`: S/MIME signed documents whose signature verifies
//!   with the permissions CA's key (the signer must be that CA: a document signed by
//!   another key, or changed after signing, is refused).

use std::path::Path;

use openssl::{
    asn1::{Asn1Time, Asn1TimeRef},
    pkcs7::{Pkcs7, Pkcs7Flags},
    pkey::PKey,
    stack::Stack,
    x509::{X509, store::X509StoreBuilder},
};

/// Checks the credentials in the enclave folder `dir` (which holds the six files:
/// [`super::ENCLAVE_FILES`]). `Err`: `'FILE': reason`, one line.
pub fn check(dir: &Path) -> Result<(), String> {
    let now = Asn1Time::days_from_now(0).map_err(|e| format!("cannot read the clock: {e}"))?;
    let identity_ca = certificate(dir, "identity_ca.cert.pem", &now)?;
    let permissions_ca = certificate(dir, "permissions_ca.cert.pem", &now)?;
    let cert = certificate(dir, "cert.pem", &now)?;
    let cert_path = dir.join("cert.pem");
    let ca_key = identity_ca.public_key().map_err(|e| fail(&dir.join("identity_ca.cert.pem"), e))?;
    if !cert.verify(&ca_key).unwrap_or(false) {
        return Err(format!(
            "'{}': not signed by the identity CA '{}' (issuer {}, the CA is {})",
            cert_path.display(),
            dir.join("identity_ca.cert.pem").display(),
            name(cert.issuer_name()),
            name(identity_ca.subject_name())
        ));
    }
    let key_path = dir.join("key.pem");
    let key = PKey::private_key_from_pem(&read(&key_path)?).map_err(|e| {
        format!("'{}': not a PEM private key without a password: {}", key_path.display(), first_reason(&e))
    })?;
    let cert_key = cert.public_key().map_err(|e| fail(&cert_path, e))?;
    if !cert_key.public_eq(&key) {
        return Err(format!("'{}': not the key of '{}'", key_path.display(), cert_path.display()));
    }
    for doc in ["governance.p7s", "permissions.p7s"] {
        signed_by(&dir.join(doc), &permissions_ca, &dir.join("permissions_ca.cert.pem"))?;
    }
    Ok(())
}

fn read(path: &Path) -> Result<Vec<u8>, String> {
    std::fs::read(path).map_err(|e| format!("'{}' cannot be read: {e}", path.display()))
}

fn fail(path: &Path, e: openssl::error::ErrorStack) -> String {
    format!("'{}': {}", path.display(), first_reason(&e))
}

/// OpenSSL's first reason, without its codes ("bad decrypt", "no start line").
fn first_reason(e: &openssl::error::ErrorStack) -> String {
    e.errors().first().and_then(|r| r.reason()).unwrap_or("unknown OpenSSL error").to_string()
}

fn name(n: &openssl::x509::X509NameRef) -> String {
    let parts: Vec<String> = n
        .entries()
        .map(|e| {
            let key = e.object().nid().short_name().unwrap_or("?");
            let value = e.data().to_string().unwrap_or_default();
            format!("{key}={value}")
        })
        .collect();
    parts.join(",")
}

/// A PEM certificate, valid at `now`.
fn certificate(dir: &Path, file: &str, now: &Asn1TimeRef) -> Result<X509, String> {
    let path = dir.join(file);
    let cert = X509::from_pem(&read(&path)?)
        .map_err(|e| format!("'{}': not a PEM certificate: {}", path.display(), first_reason(&e)))?;
    if cert.not_after() < now {
        return Err(format!("'{}': certificate expired on {}", path.display(), cert.not_after()));
    }
    if cert.not_before() > now {
        return Err(format!("'{}': certificate not valid before {}", path.display(), cert.not_before()));
    }
    Ok(cert)
}

/// The S/MIME document at `path` verifies, signed by `ca` (only `ca` may be the signer).
fn signed_by(path: &Path, ca: &X509, ca_path: &Path) -> Result<(), String> {
    let bytes = read(path)?;
    let (p7, content) = Pkcs7::from_smime(&bytes)
        .map_err(|e| format!("'{}': not an S/MIME signed document: {}", path.display(), first_reason(&e)))?;
    let mut signers = Stack::new().map_err(|e| fail(path, e))?;
    signers.push(ca.clone()).map_err(|e| fail(path, e))?;
    let store = X509StoreBuilder::new().map_err(|e| fail(path, e))?.build();
    // NOINTERN: the signer is looked for among `signers` only (not the certificates the
    // document carries); NOVERIFY: that CA is trusted as is (it is the trust anchor).
    p7.verify(&signers, &store, content.as_deref(), None, Pkcs7Flags::NOINTERN | Pkcs7Flags::NOVERIFY).map_err(|e| {
        format!(
            "'{}': signature does not verify with the permissions CA '{}' ({})",
            path.display(),
            ca_path.display(),
            first_reason(&e)
        )
    })
}

// ------------------------------------------------------------------------------------------

#[cfg(test)]
mod tests {
    use super::*;
    use openssl::{
        asn1::Asn1Integer,
        bn::BigNum,
        ec::{EcGroup, EcKey},
        hash::MessageDigest,
        nid::Nid,
        pkey::Private,
        x509::{X509Builder, X509NameBuilder},
    };

    fn key() -> PKey<Private> {
        let group = EcGroup::from_curve_name(Nid::X9_62_PRIME256V1).unwrap();
        PKey::from_ec_key(EcKey::generate(&group).unwrap()).unwrap()
    }

    /// A certificate for `cn` with `key`, signed by `issuer` (`None`: self-signed), valid
    /// from `from` to `to` days from now.
    fn cert(cn: &str, key: &PKey<Private>, issuer: Option<(&X509, &PKey<Private>)>, from: i64, to: i64) -> X509 {
        let mut name = X509NameBuilder::new().unwrap();
        name.append_entry_by_nid(Nid::COMMONNAME, cn).unwrap();
        let name = name.build();
        let mut b = X509Builder::new().unwrap();
        b.set_version(2).unwrap();
        let serial = Asn1Integer::from_bn(&BigNum::from_u32(rand::random::<u32>() >> 1).unwrap()).unwrap();
        b.set_serial_number(&serial).unwrap();
        b.set_subject_name(&name).unwrap();
        b.set_issuer_name(issuer.map_or(&name, |(c, _)| c.subject_name())).unwrap();
        b.set_pubkey(key).unwrap();
        let now = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap().as_secs() as i64;
        b.set_not_before(&Asn1Time::from_unix(now + from * 86400).unwrap()).unwrap();
        b.set_not_after(&Asn1Time::from_unix(now + to * 86400).unwrap()).unwrap();
        b.sign(issuer.map_or(key, |(_, k)| k), MessageDigest::sha256()).unwrap();
        b.build()
    }

    /// `doc` signed as sros2 signs it (S/MIME, detached, text) by `ca`.
    fn smime(doc: &str, ca: &X509, ca_key: &PKey<Private>) -> Vec<u8> {
        let flags = Pkcs7Flags::DETACHED | Pkcs7Flags::TEXT;
        let p7 = Pkcs7::sign(ca, ca_key, &Stack::new().unwrap(), doc.as_bytes(), flags).unwrap();
        p7.to_smime(doc.as_bytes(), flags).unwrap()
    }

    struct Enclave {
        dir: std::path::PathBuf,
        ca: X509,
        ca_key: PKey<Private>,
    }

    impl Enclave {
        /// A good enclave (one CA for identity and permissions, as `ros2 security` makes).
        fn new(tag: &str) -> Enclave {
            let dir = std::env::temp_dir().join(format!("tracer_calib_cred_{}_{tag}", std::process::id()));
            let _ = std::fs::remove_dir_all(&dir);
            std::fs::create_dir_all(&dir).unwrap();
            let ca_key = key();
            let ca = cert("sros2testCA", &ca_key, None, -1, 3650);
            let k = key();
            let c = cert("/tracer", &k, Some((&ca, &ca_key)), -1, 3650);
            let e = Enclave { dir, ca, ca_key };
            e.write("identity_ca.cert.pem", &e.ca.to_pem().unwrap());
            e.write("permissions_ca.cert.pem", &e.ca.to_pem().unwrap());
            e.write("cert.pem", &c.to_pem().unwrap());
            e.write("key.pem", &k.private_key_to_pem_pkcs8().unwrap());
            e.write("governance.p7s", &smime("<dds><domain_access_rules/></dds>\n", &e.ca, &e.ca_key));
            e.write("permissions.p7s", &smime("<dds><permissions/></dds>\n", &e.ca, &e.ca_key));
            e
        }

        fn write(&self, file: &str, bytes: &[u8]) {
            std::fs::write(self.dir.join(file), bytes).unwrap();
        }

        fn check_err(&self) -> String {
            let err = check(&self.dir).unwrap_err();
            assert!(!err.contains('\n'), "{err}");
            err
        }
    }

    impl Drop for Enclave {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.dir);
        }
    }

    #[test]
    fn good_enclave_passes() {
        let e = Enclave::new("good");
        check(&e.dir).unwrap();
    }

    #[test]
    fn expired_or_not_yet_valid_certificate() {
        let e = Enclave::new("expired");
        let k = key();
        e.write("key.pem", &k.private_key_to_pem_pkcs8().unwrap());
        e.write("cert.pem", &cert("/tracer", &k, Some((&e.ca, &e.ca_key)), -30, -1).to_pem().unwrap());
        let err = e.check_err();
        assert!(err.contains("cert.pem'") && err.contains("certificate expired on"), "{err}");
        e.write("cert.pem", &cert("/tracer", &k, Some((&e.ca, &e.ca_key)), 2, 30).to_pem().unwrap());
        let err = e.check_err();
        assert!(err.contains("cert.pem'") && err.contains("not valid before"), "{err}");
        let ca_key = key();
        e.write("identity_ca.cert.pem", &cert("oldCA", &ca_key, None, -30, -1).to_pem().unwrap());
        let err = e.check_err();
        assert!(err.contains("identity_ca.cert.pem'") && err.contains("expired"), "{err}");
    }

    #[test]
    fn certificate_of_another_ca() {
        let e = Enclave::new("foreign");
        let other_key = key();
        let other = cert("otherCA", &other_key, None, -1, 3650);
        let k = key();
        e.write("key.pem", &k.private_key_to_pem_pkcs8().unwrap());
        e.write("cert.pem", &cert("/tracer", &k, Some((&other, &other_key)), -1, 3650).to_pem().unwrap());
        let err = e.check_err();
        assert!(err.contains("cert.pem'") && err.contains("not signed by the identity CA"), "{err}");
        assert!(err.contains("issuer CN=otherCA") && err.contains("the CA is CN=sros2testCA"), "{err}");
    }

    #[test]
    fn key_of_another_certificate() {
        let e = Enclave::new("key");
        e.write("key.pem", &key().private_key_to_pem_pkcs8().unwrap());
        let err = e.check_err();
        assert!(err.contains("key.pem'") && err.contains("not the key of"), "{err}");
        e.write("key.pem", b"-----BEGIN PRIVATE KEY-----\nnope\n-----END PRIVATE KEY-----\n");
        let err = e.check_err();
        assert!(err.contains("key.pem'") && err.contains("not a PEM private key"), "{err}");
    }

    #[test]
    fn permissions_signed_by_another_ca() {
        let e = Enclave::new("perm");
        let other_key = key();
        let other = cert("otherCA", &other_key, None, -1, 3650);
        e.write("permissions.p7s", &smime("<dds><permissions/></dds>\n", &other, &other_key));
        let err = e.check_err();
        assert!(err.contains("permissions.p7s'") && err.contains("signature does not verify"), "{err}");
    }

    #[test]
    fn tampered_governance() {
        let e = Enclave::new("gov");
        let signed = String::from_utf8(smime(
            "<dds><rtps_protection_kind>ENCRYPT</rtps_protection_kind></dds>\n",
            &e.ca,
            &e.ca_key,
        ))
        .unwrap();
        let tampered = signed.replacen("ENCRYPT</rtps", "NONE</rtps", 1);
        assert_ne!(signed, tampered);
        e.write("governance.p7s", tampered.as_bytes());
        let err = e.check_err();
        assert!(err.contains("governance.p7s'") && err.contains("signature does not verify"), "{err}");
        e.write("governance.p7s", b"<dds/>\n");
        let err = e.check_err();
        assert!(err.contains("governance.p7s'") && err.contains("not an S/MIME signed document"), "{err}");
    }
}
